#!/usr/bin/env python3
"""Hostile-input sweep of whole commands, beyond the readers (tools/mutate_lens_files.py):
mutated copies of real lens files go through the commands a user runs on a lens.

Each case changes one or two numbers of a copy (in `commands` mode also by extremes such as
1e300 or 89.9999) and in three cases of ten deletes or repeats a line. Two modes:
- `commands`: analyze, plot, report, psf, mtf, trace (with a file of hostile rays), bake and
  render at small sizes. Each run must exit 0 or 2; a refusal must print `error:` as the first
  line of stderr and leave nothing where the output was asked for; a success must print no
  `NaN` or `inf`; no run may take over 30 s.
- `round-trip`: `lens convert` to RON or Zemax, then `analyze --json` of both files must agree
  (exit status, and every number to 1e-9 relative, the lens name and the conditions' origins
  aside). pbrt output is converted but not compared: a pbrt file holds one index per medium and
  no conditions. A RON file at constant indices (`--indices-at-nm`, at the wavelength `analyze`
  takes) must give the same first-order data and monochromatic Seidel sums there.

A failing case is kept as bad-N.<ext> in the output directory, with a JSON line on stdout.

Run from the repo root after `cargo build --release`:
    python3 tools/fuzz_commands.py commands --seconds 600 --seed 1 --out /tmp/fuzz-commands
    python3 tools/fuzz_commands.py round-trip --seconds 600 --seed 1 --out /tmp/fuzz-round-trip
"""
import argparse
import glob
import json
import os
import random
import re
import shutil
import subprocess
import time

BINARY = os.path.abspath(os.path.join("target", "release", "lensbake"))
NUMBER = re.compile(rb"(?<![A-Za-z_])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
EXTREMES = [b"0", b"-0", b"1e300", b"-1e300", b"1e-300", b"1e-12", b"90", b"89.9999", b"1e15",
            b"-1", b"2", b"0.5", b"1e6", b"-1e6", b"360", b"1e-6", b"1e9", b"-1e9"]
SCALES = [-1, 10, 0.1, 1e3, 1e-3, 1.0000001, 0.999, 1.1, 0.9, 2, 0.5]
PLOTS = ("layout ray-fan spot lsa field-curves distortion lateral-color vignetting seidel "
         "opd-fan wavefront-map psf mtf through-focus-mtf mtf-field").split()


def seeds():
    files = []
    for pattern in ["tests/data/corpus/*.zmx", "tests/data/corpus/*.ZMX",
                    "tests/data/corpus/*.seq", "lenses/*.ron", "examples/lenses/*"]:
        files += glob.glob(pattern)
    return sorted(f for f in files if os.path.isfile(f) and not f.endswith((".json", ".md")))


def mutate(rng, data, extremes):
    """One or two numbers replaced (by an extreme, or scaled), and in three cases of ten a line
    deleted or repeated."""
    if rng.random() < 0.3:
        lines = data.split(b"\n")
        i = rng.randrange(len(lines))
        if rng.random() < 0.5:
            del lines[i]
        else:
            lines.insert(i, lines[rng.randrange(len(lines))])
        data = b"\n".join(lines)
    for _ in range(rng.randint(1, 2)):
        numbers = list(NUMBER.finditer(data))
        if not numbers:
            break
        m = rng.choice(numbers)
        value = rng.choice(EXTREMES) if extremes and rng.random() < 0.6 else None
        if value is None:
            try:
                value = repr(float(m.group()) * rng.choice(SCALES)).encode()
            except ValueError:
                continue
        data = data[:m.start()] + value + data[m.end():]
    return data


def run(command):
    env = dict(os.environ, XDG_RUNTIME_DIR="/tmp")
    started = time.time()
    try:
        p = subprocess.run(command, capture_output=True, timeout=60, env=env)
        return p.returncode, p.stdout, p.stderr, time.time() - started
    except subprocess.TimeoutExpired:
        return "hang", b"", b"", 60.0


def hostile_rays(rng):
    def number():
        return rng.choice([0.0, 1.0, -1.0, 1e300, -1e300, 1e-300, 5.0, 1e9, 2e9,
                           rng.uniform(-20, 20)])
    return json.dumps([{"origin": [number(), number(), rng.choice([-100.0, -1e9, number()])],
                        "direction": [number(), number(), rng.choice([1.0, -1.0, 0.0, number()])]}
                       for _ in range(rng.randint(1, 5))])


def command_for(rng, lens, work, outputs):
    field = str(rng.choice([0, 1, 5, 20, 45, 89]))
    kind = rng.choice(["analyze", "plot", "report", "psf", "mtf", "trace", "bake", "render"])
    # A finite object now and then, from touching the lens to far away, or a virtual one.
    near = (["--object-distance-mm=" + str(rng.choice([1e-3, 0.5, 5, 50, 500, 5000, 1e6, -5, -50]))]
            if rng.random() < 0.3 else [])
    # Real ray aiming now and then (a Zemax file's RAIM may ask for it already).
    near += ["--ray-aiming", rng.choice(["real", "paraxial"])] if rng.random() < 0.3 else []
    if kind == "analyze":
        return [BINARY, "analyze", lens, "--json", "--field-deg", field] + near
    if kind == "plot":
        return [BINARY, "plot", rng.choice(PLOTS), lens, "--out", f"{outputs}/plot.png"] + near
    if kind == "report":
        return [BINARY, "report", lens, "--out", f"{outputs}/report"] + near
    if kind == "psf":
        huygens = ["--huygens"] if rng.random() < 0.3 else []
        return [BINARY, "psf", lens, "--field-deg", field, "--samples", "16", "--grid", "32",
                "--out", f"{outputs}/psf.exr"] + huygens + near
    if kind == "mtf":
        return [BINARY, "mtf", lens, "--field-deg", field, "--samples", "16", "--grid",
                "32"] + near
    if kind == "trace":
        rays = f"{work}/rays.json"
        with open(rays, "w") as f:
            f.write(hostile_rays(rng))
        backward = ["--backward"] if rng.random() < 0.3 else []
        return [BINARY, "trace", lens, "--rays", rays, "--json"] + backward
    if kind == "bake":
        return [BINARY, "bake", lens, "--resolution", "8", "--out", f"{outputs}/table"]
    model = rng.choice(["traced", "baked", "thin", "thick", "seidel"])
    table = ["--table", f"{outputs}/table", "--bake-resolution", "8"] if model == "baked" else []
    film = ["--film-mm", str(rng.choice([0.5, 5, 100]))] if rng.random() < 0.2 else []
    return [BINARY, "render", "--lens", lens, "--model", model, "--backend", "cpu", "--width",
            "32", "--height", "24", "--spp", "4", "--out", f"{outputs}/render.exr"] + table + film


def commands_case(rng, lens, work):
    outputs = f"{work}/out"
    shutil.rmtree(outputs, ignore_errors=True)
    os.makedirs(outputs)
    command = command_for(rng, lens, work, outputs)
    status, out, err, seconds = run(command)
    if status not in (0, 2):
        return f"exit {status}", command
    if status == 2 and not err.startswith(b"error:"):
        return "refused without the error line first", command
    if status == 2 and os.listdir(outputs):
        return "refused but left output", command
    if status == 0 and re.search(rb"\b(NaN|nan|inf)\b", out):
        return "NaN or inf in the output", command
    if seconds > 30:
        return f"took {seconds:.0f} s", command
    return None, command


def without_origins(analysis):
    for key in ["lens", "conditions", "notes"]:
        analysis.pop(key, None)
    return analysis


def first_difference(a, b, path=""):
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return f"{path}: keys {sorted(set(a) ^ set(b))}"
        return next((d for k in a if (d := first_difference(a[k], b[k], f"{path}.{k}"))), None)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{path}: {len(a)} against {len(b)} entries"
        return next((d for i, (x, y) in enumerate(zip(a, b))
                     if (d := first_difference(x, y, f"{path}[{i}]"))), None)
    if isinstance(a, float) and isinstance(b, float):
        return None if abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b)) else f"{path}: {a} against {b}"
    return None if a == b else f"{path}: {a!r} against {b!r}"


def constant_indices_case(lens, work):
    """`lens convert --indices-at-nm W` at the wavelength `analyze` takes: the same first-order
    data and monochromatic Seidel sums at W (the colour terms change: no dispersion is left)."""
    converted = f"{work}/converted-at.ron"
    if os.path.exists(converted):
        os.remove(converted)
    before = run([BINARY, "analyze", lens, "--json"])
    wavelength = json.loads(before[1])["wavelength_nm"] if before[0] == 0 else 587.5618
    command = [BINARY, "lens", "convert", lens, converted, "--indices-at-nm", repr(wavelength)]
    status, _, err, _ = run(command)
    if status not in (0, 2):
        return f"convert exit {status}", command
    if status == 2 and (not err.startswith(b"error:") or os.path.exists(converted)):
        return "convert refused without the error line first, or left a file", command
    if status != 0 or before[0] != 0:
        return None, command
    after = run([BINARY, "analyze", converted, "--json", "--wavelength-nm", repr(wavelength)])
    if after[0] != 0:
        return f"analyze exits {after[0]} at constant indices: {after[2][:200]!r}", command
    a, b = json.loads(before[1]), json.loads(after[1])
    for key in ["first_order"]:
        difference = first_difference(a[key], b[key], key)
        if difference:
            return f"analysis at constant indices differs at {difference}", command
    for key in ["sums", "transverse", "wavefront"]:
        difference = first_difference(a["seidel"][key], b["seidel"][key], f"seidel.{key}")
        if difference:
            return f"analysis at constant indices differs at {difference}", command
    return None, command


def round_trip_case(rng, lens, work):
    target = rng.choice(["ron", "zmx", "dat", "ron at one wavelength"])
    if target == "ron at one wavelength":
        return constant_indices_case(lens, work)
    converted = f"{work}/converted.{target}"
    if os.path.exists(converted):
        os.remove(converted)
    command = [BINARY, "lens", "convert", lens, converted]
    status, _, err, _ = run(command)
    if status not in (0, 2):
        return f"convert exit {status}", command
    if status == 2 and (not err.startswith(b"error:") or os.path.exists(converted)):
        return "convert refused without the error line first, or left a file", command
    if status != 0 or target == "dat":
        return None, command
    before = run([BINARY, "analyze", lens, "--json"])
    after = run([BINARY, "analyze", converted, "--json"])
    if before[0] != after[0]:
        return f"analyze exits {before[0]}, {after[0]} after conversion: {after[2][:200]!r}", command
    if before[0] == 0:
        difference = first_difference(without_origins(json.loads(before[1])),
                                      without_origins(json.loads(after[1])))
        if difference:
            return f"analysis differs after conversion at {difference}", command
    return None, command


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("mode", choices=["commands", "round-trip"])
    parser.add_argument("--seconds", type=float, default=600)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default="/tmp/fuzz-commands")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    os.makedirs(args.out, exist_ok=True)
    files = seeds()
    case = commands_case if args.mode == "commands" else round_trip_case
    deadline = time.time() + args.seconds
    runs, failures = 0, 0
    while time.time() < deadline:
        source = rng.choice(files)
        with open(source, "rb") as f:
            data = mutate(rng, f.read(), extremes=args.mode == "commands")
        extension = os.path.splitext(source)[1] or ".ron"
        lens = f"{args.out}/case{extension}"
        with open(lens, "wb") as f:
            f.write(data)
        why, command = case(rng, lens, args.out)
        runs += 1
        if why:
            failures += 1
            kept = f"{args.out}/bad-{failures}{extension}"
            shutil.copyfile(lens, kept)
            print(json.dumps({"failure": why, "case": kept, "from": source,
                              "command": [kept if c == lens else c for c in command[1:]]}),
                  flush=True)
    print(f"{runs} cases, {failures} failures")


if __name__ == "__main__":
    main()
