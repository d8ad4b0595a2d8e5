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
mlct.generate.samplers.portable_noise.generate_with_portable_noise). --candidates: best of N by the
critic (the page's default is the model's, 8 for the bundled model); --sequences also times
two-action prompts ("A, then B": two parts, each encoded and sampled, chained), 6 s.

    python bench/web_speed.py --quantization [--prompts 30]      # about 2 minutes
    python bench/web_speed.py --unpack GZ_SITE PLAIN_SITE [--repeats 5]

--quantization: what the site's smaller graphs cost, in Python (ONNX Runtime), same noise. It
exports the bundled model with --text-encoder float32, int8, int8-weights and --denoiser int8
and prints, for the benchmark's prompts (bench/data/quality_prompts.json), the cosine of each
text encoder's sentence vectors with the float32 ones, the mean joint distance between motions
made with the same portable noise (4 s, 5 NFE) by each variant and by the float32 reference,
another seed's distance for scale, and the graphs' sizes.
--unpack: what storing the largest files gzipped costs when the page opens: the page's own
fetchBytes (fetch, then DecompressionStream) of the text encoder and ONNX Runtime's WASM binary
from a default site and a `--no-gzip` one, the fastest of --repeats loads, in ms.
"""

from __future__ import annotations

import argparse
import functools
import gzip
import http.server
import json
import os
import shutil
import statistics
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

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


QUANT_VARIANTS = {"float32 text, float16 denoiser (reference)": {"text_encoder": "float32"},
            "--text-encoder int8": {"text_encoder": "int8"},
            "--text-encoder int8-weights (default)": {"text_encoder": "int8-weights"},
            "--denoiser int8 (float32 text)": {"text_encoder": "float32", "denoiser": "int8"}}


def quantization(args: argparse.Namespace) -> None:
    import torch

    from mlct.serve.site import export_site, load_site_reference
    from mlct.serve.site.reference import generate_with_portable_noise

    torch.set_num_threads(1)
    data = json.loads((Path(__file__).resolve().parent / "data" / "quality_prompts.json")
                      .read_text(encoding="utf-8"))
    texts = [item["text"] for key in ("paraphrases", "two_actions") for item in data[key]]
    with tempfile.TemporaryDirectory() as tmp:
        generators = {}
        for i, (name, options) in enumerate(QUANT_VARIANTS.items()):
            site = export_site("bundled", Path(tmp) / f"site{i}", **options)
            generators[name] = load_site_reference(site, threads=1)
            sizes = {p.name: p.stat().st_size / 1e6 for p in (site / "model").glob("*.onnx*")}
            print(f"{name}: " + ", ".join(f"{k} {v:.1f} MB" for k, v in sorted(sizes.items())))
        names = list(generators)
        reference = generators[names[0]]
        ref_emb = reference.encode_text(texts)
        ref_motions = [generate_with_portable_noise(reference, t, 80, 5, i)[1]
                       for i, t in enumerate(texts[:args.prompts])]
        other_seed = [np.linalg.norm(generate_with_portable_noise(reference, t, 80, 5, i + 1000)[1]
                                     - m, axis=-1).mean()
                      for i, (t, m) in enumerate(zip(texts, ref_motions))]
        print(f"\n{len(texts)} prompts for the cosines, {len(ref_motions)} motions (80 frames)")
        print(f"for scale, another seed: mean joint distance median {np.median(other_seed):.3f} m")
        for name in names[1:]:
            generator = generators[name]
            cos = (generator.encode_text(texts) * ref_emb).sum(1).numpy()
            gaps = [np.linalg.norm(generate_with_portable_noise(generator, t, 80, 5, i)[1] - m,
                                   axis=-1).mean()
                    for i, (t, m) in enumerate(zip(texts, ref_motions))]
            print(f"{name}: cosine min {cos.min():.4f} median {np.median(cos):.4f}; mean joint "
                  f"distance median {np.median(gaps):.3f} m, worst {max(gaps):.3f} m")


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


UNPACK_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu"]


def unpack(args: argparse.Namespace) -> None:
    from playwright.sync_api import sync_playwright

    sites = {"gzipped": Path(args.unpack[0]).resolve(), "plain": Path(args.unpack[1]).resolve()}
    urls = {}
    for name, site in sites.items():
        config = json.loads((site / "model" / "model.json").read_text())
        urls[name] = {"text_encoder": f"model/{config['graphs']['text_encoder']}",
                      "wasm": f"vendor/{config['wasm']}"}
    root = Path(os.path.commonpath(list(sites.values())))  # both sites under one server
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0),
                                             functools.partial(QuietHandler, directory=str(root)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=shutil.which("chromium")
                                        or "/usr/bin/chromium", args=UNPACK_FLAGS)
            page = browser.new_page()
            path = {name: "/" + site.relative_to(root).as_posix() for name, site in sites.items()}
            page.goto(f"{base}{path['gzipped']}/index.html")
            for key in ("text_encoder", "wasm"):
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
    parser.add_argument("--quantization", action="store_true", help="the graphs' choices (above)")
    parser.add_argument("--prompts", type=int, default=30, help="with --quantization: motions")
    parser.add_argument("--unpack", nargs=2, metavar=("GZ_SITE", "PLAIN_SITE"), default=None,
                        help="opening a gzipped site against a --no-gzip one (above)")
    parser.add_argument("--repeats", type=int, default=5, help="with --unpack")
    args = parser.parse_args()
    if args.quantization:
        return quantization(args)
    if args.unpack:
        return unpack(args)
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
