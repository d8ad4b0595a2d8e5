"""The static site's own time per sentence, in headless Chromium (ONNX Runtime Web, WASM).

    python bench/web_speed.py [--site SITE] [--threads 1 2] [--sentences 20] [--nfe 5]
        [--candidates 1 8] [--sequences] [--text-encoder int8]

Exports the bundled model to a temporary site unless --site is given, serves it from a static
server that sends the COOP/COEP headers (cross-origin isolation: without it the browser has no
SharedArrayBuffer and ONNX Runtime Web runs on one thread), opens the page with ?threads=N and
times window.mlct.generate on new sentences (each runs the text encoder; nothing is memoised):
4 s motions (80 frames), batch 1. Prints the median and quartiles of the page's own timing
(performance.now() around tokenize -> text encoder -> sampler -> decoder -> joints) and of its
parts, after WARMUP sentences. For comparison, on the same machine at the same time: the same
graphs and steps in Python (ONNX Runtime's native CPU build, --python-threads threads,
mlct.generate.portable_noise.generate_with_portable_noise). --candidates: best of N by the
critic (the page's default is the model's, 8 for the bundled model); --sequences also times
two-action prompts ("A, then B": two parts, each encoded and sampled, chained), 6 s.
"""

from __future__ import annotations

import argparse
import functools
import gzip
import http.server
import shutil
import statistics
import tempfile
import threading
import time
from pathlib import Path

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
WARMUP = 3
SUBJECTS = ["a person", "someone", "a man", "a woman", "the figure"]
ACTIONS = ["walks forward", "jumps up and down", "waves the right hand", "turns around",
           "sits down", "kicks with the left leg", "bows", "runs in a circle", "crouches",
           "raises both arms", "walks backward slowly", "hops on one foot"]


class Isolated(http.server.SimpleHTTPRequestHandler):
    """Static files with the headers that make the page cross-origin isolated."""

    def end_headers(self):
        self.send_header("Cross-Origin-Opener-Policy", "same-origin")
        self.send_header("Cross-Origin-Embedder-Policy", "require-corp")
        super().end_headers()

    def log_message(self, *args):
        pass


def sentences(count: int, sequence: bool = False, first: int = 0) -> list[str]:
    """count new sentences ("take i", i from `first`, on every part: nothing memoised)."""
    if sequence:
        return [f"{SUBJECTS[i % len(SUBJECTS)]} {ACTIONS[(i * 7) % len(ACTIONS)]} (take {i}), "
                f"then {ACTIONS[(i * 5 + 3) % len(ACTIONS)]} (take {i})"
                for i in range(first, first + count)]
    return [f"{SUBJECTS[i % len(SUBJECTS)]} {ACTIONS[(i * 7) % len(ACTIONS)]}, take {i}"
            for i in range(first, first + count)]


def quartiles(values: list[float]) -> str:
    q1, q2, q3 = statistics.quantiles(values, n=4)
    return f"{q2:7.1f} ms  (quartiles {q1:.1f} - {q3:.1f})"


def measure(url: str, threads: int, count: int, nfe: int, candidates: list[int],
            sequences: bool) -> None:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=shutil.which("chromium")
                                    or "/usr/bin/chromium", args=FLAGS)
        page = browser.new_page()
        start = time.perf_counter()
        page.goto(f"{url}?threads={threads}")
        page.wait_for_function("window.mlct && window.mlct.ready", timeout=180_000)
        # opening the page: fetch, unpack (gzipped graphs and runtime), sessions, a first motion
        loaded = (time.perf_counter() - start) * 1000
        isolated = page.evaluate("window.crossOriginIsolated")
        print(f"threads {threads} (cross-origin isolated: {isolated}); the page ready (first "
              f"motion drawn) after {loaded:.0f} ms")
        for sequence in (False, True) if sequences else (False,):
            frames = 120 if sequence else 80
            for n in candidates:
                timings = []
                for i, text in enumerate(sentences(WARMUP + count, sequence, first=1000 * n)):
                    timing = page.evaluate(
                        "async (r) => (await window.mlct.model.generate(r)).timing",
                        {"text": text, "frames": frames, "nfe": nfe, "seed": i, "candidates": n})
                    if i >= WARMUP:
                        timings.append(timing)
                kind = "two-action prompts" if sequence else "new sentences"
                print(f" {count} {kind}, {nfe} NFE, best of {n}, {frames} frames:")
                for key, name in (("total_ms", "per sentence"), ("text_ms", "  text encoder"),
                                  ("sample_ms", f"  sampler ({nfe} denoiser runs a part)"),
                                  ("decode_ms", "  decoder + joints")):
                    print(f"  {name:<36} {quartiles([t[key] for t in timings])}")
        browser.close()


def measure_python(site: Path, threads: int, count: int, nfe: int) -> None:
    from mlct.serve.site.reference import generate_with_portable_noise
    from mlct.serve.site import load_site_reference

    generator = load_site_reference(site, threads=threads)
    times = []
    for i, text in enumerate(sentences(WARMUP + count)):
        start = time.perf_counter()
        generate_with_portable_noise(generator, f"{text}.", 80, nfe, i, candidates=1)  # not memoised
        if i >= WARMUP:
            times.append((time.perf_counter() - start) * 1000)
    print(f"python onnxruntime (native), {threads} thread(s), the same graphs, best of 1: "
          f"{quartiles(times)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--site", type=Path, default=None, help="an exported site (default: "
                        "export the bundled model to a temporary folder)")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--sentences", type=int, default=20)
    parser.add_argument("--nfe", type=int, default=5)
    parser.add_argument("--python-threads", type=int, default=1)
    parser.add_argument("--candidates", type=int, nargs="+", default=[1, 8])
    parser.add_argument("--sequences", action="store_true")
    parser.add_argument("--text-encoder", default="int8", help="export-web's --text-encoder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        site = args.site
        if site is None:
            from mlct.serve.site import export_site

            site = export_site("bundled", Path(tmp) / "site", text_encoder=args.text_encoder)
        from mlct.serve.site import site_size

        packed = sum(len(gzip.compress(f.read_bytes(), 6)) for f in Path(site).rglob("*")
                     if f.is_file())
        print(f"site: {site_size(site)['total'] / 1e6:.1f} MB, {packed / 1e6:.1f} MB gzipped")
        server = http.server.ThreadingHTTPServer(
            ("127.0.0.1", 0), functools.partial(Isolated, directory=str(site)))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        url = f"http://127.0.0.1:{server.server_address[1]}/"
        try:
            for threads in args.threads:
                measure(url, threads, args.sentences, args.nfe, args.candidates, args.sequences)
            measure_python(Path(site), args.python_threads, args.sentences, args.nfe)
        finally:
            server.shutdown()


if __name__ == "__main__":
    main()
