#!/usr/bin/env bash
# The Python package: install it from python/ into a fresh virtual environment (as a user's
# `pip install ./python` does: maturin from PyPI, the crate built in this workspace's target/),
# then run its pytest suite against the release command line the cargo tests built.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! python3 -c 'import ensurepip, venv' >/dev/null 2>&1; then
  export DEBIAN_FRONTEND=noninteractive
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq python3 python3-venv python3-pip >/dev/null
fi

venv=target/ci-python
rm -rf "$venv"
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet ./python pytest
cargo build --release --locked --bin lensbake
# pytest exits 5 when it collects no test, which fails this script like any other failure.
LENSBAKE_CLI="$PWD/target/release/lensbake" "$venv/bin/python" -m pytest python/tests -q
