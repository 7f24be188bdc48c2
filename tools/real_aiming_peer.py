"""Writes tests/data/real_aiming_peer.json: optiland's real ray aiming on a corpus lens that asks
for it (Zemax RAIM 2), for tests/real_aiming.rs.

optiland 0.6.3 aims each ray iteratively at (px, py) times the stop radius on the stop surface;
with an f-number or pupil-diameter aperture that radius is where the real axial ray through the
rim of the paraxial entrance pupil crosses the stop. For each field angle (degrees, y-z plane)
and pupil point the file records where the aimed ray crosses the stop and the last surface
(x, y, mm) and its direction cosines (L, M) after the last surface. The file's vignetting
factors are set to zero.

Run from the repository root with optiland 0.6.3 installed:
    python tools/real_aiming_peer.py
"""
import json
import warnings

import numpy as np
from optiland.fileio import load_zemax_file

warnings.filterwarnings("ignore")

LENS = "rayoptics__US00583336-2-scaled.zmx"
# Relative pupil points, meridional and skew.
PUPIL = [[0.0, -1.0], [0.0, -0.5], [0.0, 0.5], [0.0, 1.0], [1.0, 0.0], [0.6, 0.6], [-0.3, 0.9]]
FIELD_FRACTIONS = [0.0, 0.7, 1.0]


def scalar(values, index):
    return float(np.ravel(values[index])[0])


def main():
    optic = load_zemax_file("tests/data/corpus/" + LENS)
    # The file's vignetting factors (VDYN, VCYN) shrink optiland's pupil coordinates; lensbake
    # reads the pupil whole.
    for field in optic.fields.fields:
        field.vx = field.vy = 0.0
    optic.ray_tracer.set_aiming("iterative", max_iter=100, tol=1e-12)
    top_deg = max(abs(f.y) for f in optic.fields.fields)
    stop = optic.surfaces.stop_index
    s = optic.surfaces
    rays = []
    for fraction in FIELD_FRACTIONS:
        for px, py in PUPIL:
            optic.trace_generic(
                Hx=0.0, Hy=fraction, Px=px, Py=py, wavelength=optic.primary_wavelength
            )
            # The last surface before the image surface.
            last = len(s.x) - 2
            rays.append({
                "field_deg": fraction * top_deg,
                "pupil": [px, py],
                "stop": [scalar(s.x, stop), scalar(s.y, stop)],
                "last_surface": [scalar(s.x, last), scalar(s.y, last)],
                "direction": [scalar(s.L, last), scalar(s.M, last)],
            })
    axial = rays[FIELD_FRACTIONS.index(0.0) * len(PUPIL) + PUPIL.index([0.0, 1.0])]
    out = {
        "lens": LENS,
        "peer": "optiland 0.6.3, ray aiming 'iterative' (tolerance 1e-12)",
        "wavelength_nm": optic.primary_wavelength * 1000.0,
        "stop_radius_mm": axial["stop"][1],
        "rays": rays,
    }
    with open("tests/data/real_aiming_peer.json", "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
