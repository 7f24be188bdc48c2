"""Baked against traced on every bundled lens: the renderer's CPU twin on one thread, the demo
scene at 200x150 and 64 samples per pixel, one `lensbake bench render` per lens and table size
(thin, traced and baked frames in the same run), repeated in rounds.

    cargo build --release
    python3 benches/baked_vs_traced.py [--lenses a,b] [--sizes 16,32,64,128] [--rounds 3]
                                       [--out target/baked-vs-traced]

Prints one markdown row per lens: the traced and thin frames (medians over every run), the
free-lookup bound traced / thin (what a baked lens would reach were its lookup as cheap as the
thin lens's few operations a sample: the frame both models share stays), and baked / traced at
each table size (ratio of the medians). Tables are baked once, on every core, into --out; the
rounds run pinned to core 0 (`taskset`, where present) with RAYON_NUM_THREADS=1.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys

# Lenses that cannot focus on the demo scene's 2 m chart: the reflex lens's front focal point
# lies 5.4 m out.
FOCUS_MM = {"reflex-1000mm-f7.5": 20000}
DEMO_FOCUS_MM = 2000


def bundled_lenses(binary):
    listing = subprocess.run([binary, "lens", "list"], check=True, capture_output=True, text=True)
    return [line.split()[0] for line in listing.stdout.splitlines() if line.strip()]


def bench_render(binary, lens, size, models, out, pinned, width, height, spp):
    """One `bench render` run; returns {model: seconds} of its CPU rows."""
    run_dir = os.path.join(out, "runs", f"{lens}-{size}")
    command = [
        binary, "bench", "render", "--lens", lens, "--models", models, "--backends", "cpu",
        "--width", str(width), "--height", str(height), "--spp", str(spp),
        "--focus-mm", str(FOCUS_MM.get(lens, DEMO_FOCUS_MM)),
        "--bake-resolution", str(size), "--table", os.path.join(out, f"table-{lens}-{size}"),
        "--out", run_dir,
    ]
    env = dict(os.environ)
    if pinned:
        env["RAYON_NUM_THREADS"] = "1"
        if shutil.which("taskset"):
            command = ["taskset", "-c", "0"] + command
    shutil.rmtree(run_dir, ignore_errors=True)
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: {lens} at {size}^3: {done.stderr.strip()}")
    with open(os.path.join(run_dir, "timings.json")) as f:
        rows = json.load(f)["rows"]
    return {row["model"]: row["seconds"] for row in rows if row["backend"] == "cpu"}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--binary", default="target/release/lensbake")
    parser.add_argument("--lenses", help="comma-separated names (default: every bundled lens)")
    parser.add_argument("--sizes", default="16,32,64,128")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--width", type=int, default=200)
    parser.add_argument("--height", type=int, default=150)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--out", default="target/baked-vs-traced")
    args = parser.parse_args()
    lenses = args.lenses.split(",") if args.lenses else bundled_lenses(args.binary)
    sizes = [int(s) for s in args.sizes.split(",")]
    os.makedirs(args.out, exist_ok=True)
    # Bake each table first, on every core, with a tiny frame.
    for lens in lenses:
        for size in sizes:
            bench_render(args.binary, lens, size, "baked", args.out, False, 40, 30, 1)
    frames = {(lens, size): [] for lens in lenses for size in sizes}
    for round_index in range(args.rounds):
        print(f"round {round_index + 1} of {args.rounds}", file=sys.stderr)
        for lens in lenses:
            for size in sizes:
                frames[(lens, size)].append(bench_render(
                    args.binary, lens, size, "thin,traced,baked", args.out, True,
                    args.width, args.height, args.spp))
    header = " | ".join(f"baked / traced {s}^3" for s in sizes)
    print(f"| lens | traced ms | thin ms | free-lookup bound | {header} |")
    print("|---|---:|---:|---:|" + "---:|" * len(sizes))
    for lens in lenses:
        runs = [run for size in sizes for run in frames[(lens, size)]]
        traced = statistics.median(run["traced"] for run in runs)
        thin = statistics.median(run["thin"] for run in runs)
        ratios = []
        for size in sizes:
            at_size = frames[(lens, size)]
            ratios.append(statistics.median(r["traced"] for r in at_size)
                          / statistics.median(r["baked"] for r in at_size))
        cells = " | ".join(f"{r:.2f}" for r in ratios)
        print(f"| {lens} | {traced * 1e3:.1f} | {thin * 1e3:.1f} | {traced / thin:.2f} | {cells} |")


if __name__ == "__main__":
    main()
