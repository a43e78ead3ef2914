#!/usr/bin/env python3
"""A bake farm, simulated from measured bakes.

Measures `furbake bake` on every asset of a batch file (wall time of the whole process, the
smallest of --runs runs, and the pack's size), then simulates a farm of W workers baking N assets
drawn from those measurements (seeded, so every run prints the same table) behind a remote cache
that already holds a fraction h of the packs:

- a hit downloads the pack: latency + bytes / bandwidth;
- a miss bakes it (its measured time) and uploads the pack: latency + bytes / bandwidth;
- every worker's transfers share the cache server: a transfer gets min(link, server / W);
- the scheduler hands the next asset, in batch order, to the first free worker (what a CI matrix
  or a queue does); the makespan is when the last worker finishes. The lower bound total work / W
  is printed beside it.

Usage (from the repository root, after `cargo build --release`):

    python3 tools/farm_sim.py --furbake target/release/furbake --batch fixtures/batch/farm.toml

It prints the measured assets and a Markdown table (docs/performance.md, "Bake farms").
"""

import argparse
import heapq
import os
import random
import subprocess
import sys
import tempfile
import time
import tomllib


def measure(furbake, batch, runs):
    """(name, seconds, bytes) per asset of the batch file: `furbake bake` with its preset and
    topologies (the keys this batch file uses)."""
    base = os.path.dirname(os.path.abspath(batch))
    with open(batch, "rb") as f:
        spec = tomllib.load(f)
    defaults = spec.get("defaults", {})
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, asset in enumerate(spec["asset"]):
            src = os.path.join(base, asset["input"])
            pack = os.path.join(tmp, f"{i}.fbk")
            cmd = [furbake, "bake", src, "-o", pack, "--quiet", "--preset", asset.get("preset", defaults.get("preset", "fur"))]
            for topology in asset.get("settings", {}).get("topologies", []):
                cmd += ["--topology", topology]
            best = float("inf")
            for _ in range(runs):
                if os.path.exists(pack):
                    os.remove(pack)
                started = time.perf_counter()
                subprocess.run(cmd, check=True)
                best = min(best, time.perf_counter() - started)
            out.append((os.path.basename(src), best, os.path.getsize(pack)))
    return out


def simulate(assets, n, workers, hit_rate, latency_s, link_bps, server_bps, seed):
    """Makespan (s), lower bound (s), downloaded and uploaded bytes for one farm."""
    rng = random.Random(seed)
    bandwidth = min(link_bps, server_bps / workers)
    free = [0.0] * workers
    heapq.heapify(free)
    down = up = 0
    work = 0.0
    for _ in range(n):
        _, bake_s, size = assets[rng.randrange(len(assets))]
        transfer = latency_s + size * 8 / bandwidth
        if rng.random() < hit_rate:
            cost = transfer
            down += size
        else:
            cost = bake_s + transfer
            up += size
        work += cost
        start = heapq.heappop(free)
        heapq.heappush(free, start + cost)
    return max(free), work / workers, down, up


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--furbake", required=True)
    ap.add_argument("--batch", required=True)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--assets", type=int, default=10_000)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 8, 64, 512])
    ap.add_argument("--hit-rates", type=float, nargs="+", default=[0.0, 0.5, 0.9, 0.99])
    ap.add_argument("--latency-ms", type=float, default=5.0)
    ap.add_argument("--link-gbit", type=float, default=1.0)
    ap.add_argument("--server-gbit", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    assets = measure(args.furbake, args.batch, args.runs)
    print("| asset | `furbake bake` wall time | pack |")
    print("|---|---:|---:|")
    for name, seconds, size in assets:
        print(f"| {name} | {seconds * 1e3:.0f} ms | {size / 1e6:.2f} MB |")
    print()
    print(
        f"{args.assets} assets drawn from those (seed {args.seed}); transfers {args.latency_ms:g} ms + "
        f"size at min({args.link_gbit:g} Gbit/s, {args.server_gbit:g} Gbit/s / W)."
    )
    print()
    print("| workers W | hit rate h | makespan | lower bound | downloaded | uploaded |")
    print("|---:|---:|---:|---:|---:|---:|")
    for w in args.workers:
        for h in args.hit_rates:
            span, bound, down, up = simulate(
                assets, args.assets, w, h, args.latency_ms / 1e3, args.link_gbit * 1e9, args.server_gbit * 1e9, args.seed
            )
            print(f"| {w} | {h:g} | {span:.1f} s | {bound:.1f} s | {down / 1e9:.2f} GB | {up / 1e9:.2f} GB |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
