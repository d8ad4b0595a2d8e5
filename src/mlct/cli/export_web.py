"""`mlct export-web [--model DIR|bundled] --out SITE/`: a static site that runs the model in
the browser (mlct.serve.site)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands


def run(args: argparse.Namespace) -> int:
    from mlct.serve.site import export_site, site_size

    site = export_site(args.model, args.out, args.vendor, args.text_encoder, args.denoiser,
                       gzip=not args.no_gzip)
    size = site_size(site)
    print(f"{site}  ({size['total'] / 1e6:.1f} MB; serve it with any static file server, "
          f"e.g. python -m http.server -d {site})")
    return 0


def add_parser(commands: Commands) -> None:
    web = commands.add_parser("export-web", help="write a static web site that generates "
                              "motions in the browser (ONNX Runtime Web)")
    web.add_argument("--model", default="bundled",
                     help="model directory, or 'bundled' (the model inside mlct; default)")
    web.add_argument("--out", required=True, type=Path, help="site directory to write")
    web.add_argument("--vendor", type=Path, default=None,
                     help="folder holding the npm tarballs (onnxruntime-web, three) instead of "
                     "the download cache (~/.cache/mlct/web, or MLCT_WEB_CACHE)")
    web.add_argument("--text-encoder", choices=["int8", "int8-weights", "float32"],
                     default="int8-weights", help="MiniLM's graph: int8-weights: int8 "
                     "weights, float32 arithmetic (23 MB, the Python model's read-out pass rates; "
                     "default); int8 (23 MB, 3x faster, int8 arithmetic: 0.84 of the test "
                     "captions pass against 0.91); float32 (90 MB, the Python model's own)")
    web.add_argument("--denoiser", choices=["float16", "int8"], default="float16",
                     help="the denoiser's graph: float16 (10 MB, the model's own weights; "
                     "default) or int8 (5 MB, faster, joints a few mm off)")
    web.add_argument("--no-gzip", action="store_true",
                     help="store the text encoder and ONNX Runtime's WASM binary as they are "
                     "(52 MB) instead of gzipped (36 MB; the page unpacks them, the same numbers)")
    web.set_defaults(func=run)
