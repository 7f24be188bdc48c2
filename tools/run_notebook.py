"""Executes a notebook headless from the repository root (as CI does) and writes the executed
copy; any cell that raises, a failed assert included, fails the run with its traceback.

    python tools/run_notebook.py notebooks-out/python/lensbake-vs-optiland.ipynb [--out PATH]

Without --out the notebook is rewritten in place with its new outputs (how the committed copy
in notebooks-out/ is made). Needs nbclient, nbformat and ipykernel besides the notebook's own
imports.
"""

import argparse
import pathlib

import nbformat
from nbclient import NotebookClient

parser = argparse.ArgumentParser()
parser.add_argument("notebook", type=pathlib.Path)
parser.add_argument("--out", type=pathlib.Path)
parser.add_argument("--timeout", type=int, default=600, help="seconds a cell may run")
args = parser.parse_args()

root = pathlib.Path(__file__).resolve().parents[1]
notebook = nbformat.read(args.notebook, as_version=4)
NotebookClient(
    notebook, timeout=args.timeout, kernel_name="python3", resources={"metadata": {"path": str(root)}}
).execute()
out = args.out or args.notebook
out.parent.mkdir(parents=True, exist_ok=True)
nbformat.write(notebook, out)
print(f"executed {args.notebook} -> {out}")
