#!/usr/bin/env python3
"""Peer numbers for the lens-file corpus test: rayoptics 0.9.8's first-order data and Seidel sums.

For each file named in PEER_FILES (tests/data/corpus/), rayoptics reads the file and reports its
paraxial first-order data (EFL, BFL, entrance-pupil diameter, F-number) at its reference
wavelength, the largest field angle of the file and the sums of its third-order (Seidel)
coefficients S-I .. S-V. Lengths in mm. Written to tests/data/corpus/peers.json; tests/corpus.rs compares.

Run:  python3 -m venv /tmp/venv && /tmp/venv/bin/pip install rayoptics==0.9.8
      /tmp/venv/bin/python tools/corpus_peers.py
"""
import json
import os
import warnings

warnings.filterwarnings("ignore")
from rayoptics.environment import open_model  # noqa: E402
from rayoptics.parax.thirdorder import compute_third_order  # noqa: E402

MM_PER_UNIT = {"mm": 1.0, "cm": 10.0, "meters": 1000.0, "inches": 25.4}
CORPUS = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "corpus")
PEER_FILES = [
    "optiland__lens1.zmx",
    "rayoptics__US00583336-2-scaled.zmx",
    "rayoptics__CODV_32327.seq",
    "rayoptics__CODV_65564.seq",
    "rayoptics__unfolded_lenses_w_ape.seq",
    "rayoptics__CODV_65988_noDOE.seq",
    # rayoptics ignores FLOA (float by stop size) and takes EPD 1: only EFL and BFL compare.
    "optiland__lens_floa.zmx",
    "zospy__simple_system.zmx",
    # A double Gauss template written by OpticStudio (fields as angles, ENPD).
    "kbg__DoubleGauss.zmx",
    # Mirrors (tests/corpus.rs says why rc_f16.seq, optiland__mirror.seq and HoO-V2C18Ex27.zmx
    # are not here).
    "rayoptics__paraboloid.seq",
    "rayoptics__mangin.seq",
    "rayoptics__HoO-V2C18Ex03.zmx",
    # CODE V `stop` written out, a Mangin mirror.
    "rayoptics__achroMangin_ok.seq",
    # Three fold mirrors (CODE V BEN), which rayoptics traces folded and lensbake unfolds.
    "rayoptics__folded_lenses.seq",
    # A Maksutov-Cassegrain whose CODE V solves both programs read as the file writes them.
    "rayoptics__questar35.seq",
]


def main():
    peers = {}
    for name in PEER_FILES:
        opm = open_model(os.path.join(CORPUS, name), info=False)
        if isinstance(opm, tuple):
            opm = opm[0]
        fod = opm["analysis_results"]["parax_data"].fod
        osp = opm["optical_spec"]
        fov = osp["fov"]
        sums = compute_third_order(opm).loc["sum"]
        # rayoptics reports lengths in the file's unit (CODE V DIM I: inches); lensbake in mm.
        mm = MM_PER_UNIT[opm["system_spec"].dimensions]
        peers[name] = {
            "wavelength_nm": osp["wvls"].central_wvl,
            "field_type": str(fov.key),
            "max_field": max(abs(f.y) for f in fov.fields),
            "efl": fod.efl * mm,
            "bfl": fod.bfl * mm,
            "epd": 2 * fod.enp_radius * mm,
            "f_number": fod.fno,
            "seidel_sums": [sums[k] * mm for k in ["S-I", "S-II", "S-III", "S-IV", "S-V"]],
        }
    with open(os.path.join(CORPUS, "peers.json"), "w", encoding="utf-8") as out:
        json.dump({"tool": "rayoptics 0.9.8", "lenses": peers}, out, indent=1)
        out.write("\n")


if __name__ == "__main__":
    main()
