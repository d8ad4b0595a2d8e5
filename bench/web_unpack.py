"""What storing the site's largest files gzipped costs when the page opens: the page's own
fetchBytes (static/model.js: fetch, then DecompressionStream when the bytes are gzip's) of the
text encoder and ONNX Runtime's WASM binary from a gzipped site and from a --no-gzip one, in
headless Chromium from a local static server.

    mlct export-web --out A/ && mlct export-web --no-gzip --out B/
    python bench/web_unpack.py --gz A/ --plain B/ [--repeats 5]

Prints the fastest of --repeats loads of each file from each site, in milliseconds.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import json
import os
import shutil
import threading
from pathlib import Path

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu"]
FILES = ("text_encoder", "wasm")


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


def main() -> None:
    from playwright.sync_api import sync_playwright

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gz", type=Path, required=True, help="a site exported by default")
    parser.add_argument("--plain", type=Path, required=True, help="a site made with --no-gzip")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    sites = {"gzipped": args.gz.resolve(), "plain": args.plain.resolve()}
    urls = {}
    for name, site in sites.items():
        config = json.loads((site / "model" / "model.json").read_text())
        urls[name] = {"text_encoder": f"model/{config['graphs']['text_encoder']}",
                      "wasm": f"vendor/{config['wasm']}"}
    root = Path(os.path.commonpath(list(sites.values())))  # both sites under one server
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             functools.partial(Quiet, directory=str(root)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=shutil.which("chromium")
                                        or "/usr/bin/chromium", args=FLAGS)
            page = browser.new_page()
            path = {name: "/" + site.relative_to(root).as_posix() for name, site in sites.items()}
            page.goto(f"{base}{path['gzipped']}/index.html")
            for key in FILES:
                for name, site in sites.items():
                    url = f"{base}{path[name]}/{urls[name][key]}"
                    best = page.evaluate(
                        "async ([url, n]) => { const m = await import('./model.js'); let best = "
                        "Infinity; for (let i = 0; i < n; i++) { const t = performance.now(); "
                        "await m.fetchBytes(url); best = Math.min(best, performance.now() - t); }"
                        " return best; }", [url, args.repeats])
                    print(f"{key:<13} {name:<8} {urls[name][key]:<40} {best:7.0f} ms")
            browser.close()
    finally:
        server.shutdown()


if __name__ == "__main__":
    main()
