#!/usr/bin/env bash
# Side-by-side exact trace: optiland 0.6.3 (NumPy backend) against lensbake, same lens, same ray
# bundle, in one run. Checks that they agree, then prints the throughput ratio.
#
#   benches/peer/run.sh [--lens pbrt_dgauss_50mm] [--rays 1000000] [--repeats 5] [--sample 5000]
#
# --lens takes a truth-data table (tests/data/truth/oracle) or any lens lensbake reads of
# planes, spheres, conics, even aspheres and ideal lenses, mirrors and obscurations included,
# e.g. --lens asph-50mm-f1.8 (two even aspheres), --lens cooke-triplet (catalogue glasses,
# taken at the d line) or --lens reflex-1000mm-f7.5 (two Mangin mirrors, an obscured surface).
#
# The virtual environment goes to $PEER_VENV (default: target/peer-venv) and is reused.
set -euo pipefail
cd "$(dirname "$0")/../.."
venv="${PEER_VENV:-target/peer-venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c 'import optiland, sys; sys.exit(optiland.__version__ != "0.6.3")' 2>/dev/null; then
    "$venv/bin/pip" install --quiet optiland==0.6.3
fi
cargo build --release --quiet --bin lensbake
# numba prints pedantic internal warnings while it compiles optiland's kernels.
PYTHONWARNINGS=ignore NUMBA_DISABLE_PERFORMANCE_WARNINGS=1 \
    "$venv/bin/python" benches/peer/peer_trace.py --lensbake target/release/lensbake "$@" 2> >(grep -v -i -E "numba|warn|report|message|roots = |github|^\s*$" >&2)
