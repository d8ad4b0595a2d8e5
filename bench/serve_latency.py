"""`mlct serve` latency and dynamic batching: API round trips, concurrent clients, the browser.

    python bench/serve_latency.py [--model DIR] [--requests 10] [--clients 8] [--rounds 4]
                                  [--threads N] [--browser]

Starts `mlct serve` in a subprocess on a free localhost port and times 4 s motions at 5 NFE:
  1. one client, one text per request: round-trip medians for a prompt seen before (its text
     embedding cached) and for new prompts (the text encoder runs);
  2. N concurrent clients, each a bounded loop of requests: latency, throughput, and the batch
     sizes the server formed (from /health);
  3. with --browser (Debian chromium + playwright): click -> first frame drawn in the web page,
     the median of --requests clicks on gallery prompts and on new prompts.
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx

SECONDS, NFE = 4.0, 5
BROWSER_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                 "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader"]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def start_server(model: Path | None, port: int, threads: int | None = None) -> subprocess.Popen:
    command = [sys.executable, "-m", "mlct.cli", "serve", "--port", str(port)]
    if model is not None:
        command += ["--model", str(model)]
    if threads is not None:
        command += ["--threads", str(threads)]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise SystemExit(f"mlct serve exited: {process.stderr.read().decode()[-2000:]}")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/health", timeout=1).status_code == 200:
                return process
        except httpx.TransportError:
            time.sleep(0.2)
    process.kill()
    raise SystemExit("mlct serve did not start within 180 s")


def timed_post(client: httpx.Client, text: str, seed: int) -> tuple[float, dict]:
    start = time.perf_counter()
    reply = client.post("/generate", json={"text": text, "seconds": SECONDS, "nfe": NFE,
                                           "seed": seed})
    elapsed = (time.perf_counter() - start) * 1e3
    reply.raise_for_status()
    return elapsed, reply.json()["timing"]


def single_client(base: str, requests: int) -> None:
    with httpx.Client(base_url=base, timeout=60) as client:
        timed_post(client, "a person walks forward at a brisk pace.", 0)  # a warm connection
        rows = {"seen prompt": [timed_post(client, "a person walks forward at a brisk pace.", i)
                                for i in range(requests)],
                "new prompts": [timed_post(client, f"a person walks forward and waves {i} times",
                                           i) for i in range(requests)]}
    print(f"1 client, batch 1, {SECONDS:g} s motion, {NFE} NFE, {requests} requests each")
    for name, results in rows.items():
        trip = statistics.median(r[0] for r in results)
        server = statistics.median(r[1]["server_ms"] for r in results)
        model = statistics.median(r[1]["generate_ms"] for r in results)
        print(f"  {name:12s} round trip median {trip:6.1f} ms (server {server:6.1f}, "
              f"model {model:6.1f})")


def concurrent_clients(base: str, clients: int, rounds: int) -> None:
    before = httpx.get(f"{base}/health").json()["queue"]["batch_sizes"]
    latencies: list[float] = []
    sizes: list[int] = []
    lock = threading.Lock()

    def loop(worker: int) -> None:
        with httpx.Client(base_url=base, timeout=120) as client:
            for r in range(rounds):
                elapsed, timing = timed_post(client, f"a person runs straight ahead {worker}",
                                             worker * 1000 + r)
                with lock:
                    latencies.append(elapsed)
                    sizes.append(timing["batch_size"])

    threads = [threading.Thread(target=loop, args=(w,)) for w in range(clients)]
    start = time.perf_counter()
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    total = time.perf_counter() - start
    after = httpx.get(f"{base}/health").json()["queue"]["batch_sizes"]
    formed = {int(k): v - before.get(k, 0) for k, v in after.items() if v - before.get(k, 0)}
    print(f"{clients} concurrent clients x {rounds} requests ({clients * rounds} motions)")
    print(f"  round trip median {statistics.median(latencies):6.1f} ms, "
          f"max {max(latencies):6.1f} ms; {clients * rounds / total:5.1f} motions/s")
    print(f"  batches formed (size: count) {dict(sorted(formed.items()))}; "
          f"mean batch a request rode in {statistics.mean(sizes):.2f}")


def browser(base: str, clicks: int) -> None:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        print("browser: playwright is not installed (pip install playwright)")
        return
    chromium = "/usr/bin/chromium"
    if not os.path.exists(chromium):
        print("browser: /usr/bin/chromium is missing (apt-get install chromium)")
        return
    with tempfile.TemporaryDirectory() as profile, sync_playwright() as p:
        context = p.chromium.launch_persistent_context(
            profile, executable_path=chromium, args=BROWSER_FLAGS, headless=True,
            viewport={"width": 1280, "height": 860})
        page = context.pages[0] if context.pages else context.new_page()
        page.goto(base)
        page.wait_for_function("window.mlct && window.mlct.ready", timeout=120_000)
        done = page.evaluate("window.mlct.firstFrameMs.length")
        results = {}
        for name in ("gallery prompts", "new prompts"):
            for i in range(clicks):
                if name == "gallery prompts":
                    page.locator("#gallery button").nth(i % 10).click()
                else:
                    page.fill("#prompt", f"a person jumps forward and claps {i} times")
                    page.click("#generate")
                done += 1
                page.wait_for_function(f"window.mlct.firstFrameMs.length >= {done}",
                                       timeout=60_000)
                page.wait_for_timeout(700)  # let it play, as a person would watch it
            results[name] = page.evaluate("window.mlct.firstFrameMs")[-clicks:]
        context.close()
    print(f"browser (headless chromium, SwiftShader WebGL): click -> first frame drawn, "
          f"{SECONDS:g} s motion, {NFE} NFE, {clicks} clicks each")
    for name, values in results.items():
        print(f"  {name:15s} median {statistics.median(values):6.1f} ms "
              f"(min {min(values):.0f}, max {max(values):.0f}); goal 200 ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--requests", type=int, default=10)
    parser.add_argument("--clients", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=4, help="requests per concurrent client")
    parser.add_argument("--threads", type=int, default=None,
                        help="the server's --threads (default: its own, one per core)")
    parser.add_argument("--browser", action="store_true", help="also time the web page")
    args = parser.parse_args()
    port = free_port()
    print(f"mlct serve on 127.0.0.1:{port}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")
    server = start_server(args.model, port, args.threads)
    base = f"http://127.0.0.1:{port}"
    try:
        single_client(base, args.requests)
        concurrent_clients(base, args.clients, args.rounds)
        if args.browser:
            browser(base, args.requests)
    finally:
        server.terminate()
        server.wait(30)


if __name__ == "__main__":
    main()
