"""A 1M-ray trace called from Python against `lensbake bench trace` on the same lens and
thread count, in one run (alternating, best of --repeats each).

    python tools/python_trace_bench.py [--lens dgauss-50mm] [--rays 1000000] [--threads 2]

The rays follow the bench's distribution (field uniform over the traceable field in the y-z
plane, pupil point uniform over the paraxial entrance pupil, apertures on), drawn by NumPy
from the bundle the bench reports. The Python time is the whole `Lens.trace` call: array
conversion in, the trace, the arrays out. Like the bench, each repeat traces twice: into new
arrays (against the bench's `seconds_new_output`), then into those arrays again through `out=`
(against its `seconds`, the trace into storage that already holds results).
"""

import argparse
import json
import os
import pathlib
import subprocess
import time

parser = argparse.ArgumentParser()
parser.add_argument("--lens", default="dgauss-50mm")
parser.add_argument("--rays", type=int, default=1_000_000)
parser.add_argument("--threads", type=int, default=os.cpu_count())
parser.add_argument("--repeats", type=int, default=5)
parser.add_argument("--cli", default=str(pathlib.Path(__file__).resolve().parents[1] / "target/release/lensbake"))
args = parser.parse_args()
# rayon reads this when its pool starts, at the first trace.
os.environ["RAYON_NUM_THREADS"] = str(args.threads)

import numpy as np  # noqa: E402

import lensbake  # noqa: E402


def cli_bench():
    out = subprocess.run(
        [args.cli, "bench", "trace", args.lens, "--rays", str(args.rays), "--threads", str(args.threads), "--json"],
        capture_output=True, text=True, check=True,
    )
    return json.loads(out.stdout)


first = cli_bench()
bundle = first["bundle"]
rng = np.random.default_rng(1)
field = np.radians(rng.random(args.rays) * bundle["max_field_deg"])
radius = 0.5 * bundle["entrance_pupil_diameter"] * np.sqrt(rng.random(args.rays))
azimuth = 2 * np.pi * rng.random(args.rays)
directions = np.stack([np.zeros(args.rays), np.sin(field), np.cos(field)], axis=1)
back = (bundle["entrance_pupil_z"] - bundle["start_z"]) / directions[:, 2]
origins = np.stack(
    [radius * np.cos(azimuth), radius * np.sin(azimuth) - back * directions[:, 1], np.full(args.rays, bundle["start_z"])],
    axis=1,
)

lens = lensbake.load_lens(args.lens)
lens.trace(origins[:10_000], directions[:10_000])  # thread start-up outside the timing
python_new, python_out, cli_seconds, cli_new_output = [], [], [], []
for _ in range(args.repeats):
    start = time.perf_counter()
    results = lens.trace(origins, directions)
    python_new.append(time.perf_counter() - start)
    start = time.perf_counter()
    lens.trace(origins, directions, out=results)
    python_out.append(time.perf_counter() - start)
    run = cli_bench()
    cli_seconds.append(run["seconds"])
    cli_new_output.append(run["seconds_new_output"])
    del results

outcome = lens.trace(origins, directions)[2]
best = {name: min(times) for name, times in
        [("python_new", python_new), ("python_out", python_out), ("cli", cli_seconds), ("cli_new", cli_new_output)]}
print(json.dumps({
    "lens": args.lens,
    "rays": args.rays,
    "threads": args.threads,
    "passing_fraction_python": float((outcome == lensbake.OUTCOME_OK).mean()),
    "python_seconds_into_out": best["python_out"],
    "cli_seconds": best["cli"],
    "ratio_into_out_to_cli": best["python_out"] / best["cli"],
    "python_seconds_new_output": best["python_new"],
    "cli_seconds_new_output": best["cli_new"],
    "ratio_new_output_to_cli_new_output": best["python_new"] / best["cli_new"],
}, indent=2))
