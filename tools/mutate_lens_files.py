#!/usr/bin/env python3
"""Hostile-input sweep of the readers: mutated copies of real lens files through `lens check` and
`analyze`, which must exit 0 or 2 (a located `error:` line), never crash or hang, and print no NaN
when they succeed.

Each case takes a random file of the corpus (tests/data/corpus/, lenses/) and applies one to four
mutations: delete a line, duplicate a line elsewhere, or replace one number of a line by an
extreme (0, -1, +-1e308, 1e-320, nan, inf, 2^31, 2^64, ...). A failing case is kept as
bad-N.<ext> in the output directory.

Run from the repo root after `cargo build --release`:
    python3 tools/mutate_lens_files.py --cases 1000 --seed 1 --out /tmp/mutations
(`--only Ex66,threemir` mutates only the files whose names hold one of those parts.)
"""
import argparse
import glob
import os
import random
import subprocess

EXTREMES = ["0", "-0", "-1", "-5", "1e5", "1e308", "-1e308", "1e-320", "nan", "inf",
            "999999999", "2147483648", "18446744073709551616"]
BINARY = os.path.join("target", "release", "lensbake")


def mutate(text, rng):
    lines = text.split("\n")
    for _ in range(rng.randint(1, 4)):
        i = rng.randrange(len(lines))
        choice = rng.random()
        if choice < 0.25:
            del lines[i]
        elif choice < 0.4:
            lines.insert(i, lines[rng.randrange(len(lines))])
        else:
            words = lines[i].split(" ")
            filled = [k for k, w in enumerate(words) if w.strip()]
            if len(filled) > 1:
                words[rng.choice(filled[1:])] = rng.choice(EXTREMES)
                lines[i] = " ".join(words)
        if not lines:
            lines = [""]
    return "\n".join(lines)


def echoes(line, text):
    # A line that repeats the file, whole or after its label ("source:   <the file's text>").
    return line.strip() in text or line.split(":", 1)[-1].strip() in text


def prints_nan(output, text):
    # Titles and glass names may hold the letters; a number printed as NaN stands alone, on a
    # line that does not echo the file (a mutated title or source may hold the word itself).
    return any(
        word.strip(",;:()[]") in ("NaN", "nan", "-NaN")
        for line in output.splitlines()
        if not echoes(line, text)
        for word in line.split()
    )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cases", type=int, default=500)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default="/tmp/lensbake-mutations")
    parser.add_argument("--only", default="",
                        help="comma-separated parts of file names: mutate only those files")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    os.makedirs(args.out, exist_ok=True)
    files = sorted(glob.glob("tests/data/corpus/*.[zZsS][mMeE][xXqQ]") + glob.glob("lenses/*.ron") + glob.glob("tests/data/odd_asphere_*.zmx"))
    if args.only:
        files = [f for f in files if any(part in f for part in args.only.split(","))]
    texts = {}
    for path in files:
        raw = open(path, "rb").read()
        if raw[:2] not in (b"\xff\xfe", b"\xfe\xff"):  # UTF-16 files mutate into garbage bytes
            texts[path] = raw.decode("latin-1")
    bad = 0
    for case in range(args.cases):
        source = rng.choice(sorted(texts))
        extension = os.path.splitext(source)[1]
        path = os.path.join(args.out, f"case{extension}")
        mutated = mutate(texts[source], rng)
        with open(path, "w", encoding="latin-1") as f:
            f.write(mutated)
        for command in (["lens", "check", path], ["analyze", path]):
            try:
                run = subprocess.run([BINARY] + command, capture_output=True, text=True,
                                     timeout=60)
                failed = run.returncode not in (0, 2) or (
                    run.returncode == 0 and prints_nan(run.stdout + run.stderr, mutated))
                what = f"exit {run.returncode}: {(run.stderr.strip() or run.stdout.strip())[-200:]}"
            except subprocess.TimeoutExpired:
                failed, what = True, "no answer in 60 s"
            if failed:
                bad += 1
                kept = os.path.join(args.out, f"bad-{bad}{extension}")
                os.replace(path, kept)
                print(f"{kept} (from {source}, {command[0]}): {what}")
                break
            if run.returncode != 0:
                break
    print(f"{args.cases} cases, {bad} failed")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
