"""Writes tests/data/corpus/analyze_placed_peers.json: chief rays and ray fans traced by
rayoptics 0.9.8 through the corpus files it reads that tilt or decentre surfaces, for
tests/analyze_placed.rs.

Rays start on the plane z = 0 (surface 1's vertex) along (tan x, tan y, 1) normalised, as
lensbake launches them and as CODE V's XAN and YAN define field angles (rayoptics' own field
aiming takes two-angle fields as direction sines, 6e-4 further out at 2 degrees, and starts rays
on the file's object 1e11 mm away, where rounding of the directions alone moves them 1e-5 mm).
The chief ray's start is found here by Newton steps on rayoptics' trace until it crosses the
stop within 1e-12 mm of its centre; fan rays start 1/2 and 1 pupil radius from it along x and
y. Stored: the chief ray's point on the image plane (its own frame, mm) and each fan ray's
(x, y) there relative to it.

rayoptics 0.9.8 cannot read CODV_35571.seq (its `HMY` keyword) nor the Zemax files with toroids.

Run from the repository root with rayoptics 0.9.8 installed:
    python tools/analyze_placed_peer.py
"""
import json
import warnings

import numpy as np
from rayoptics.environment import open_model
from rayoptics.raytr.trace import trace

warnings.filterwarnings("ignore")

CORPUS = "tests/data/corpus/"
FILES = ["rayoptics__threemir.seq", "rayoptics__tilt_test.seq"]
PUPIL = [-1.0, -0.5, 0.5, 1.0]


def main():
    out = {}
    for name in FILES:
        opm = open_model(CORPUS + name)
        sm = opm["seq_model"]
        osp = opm["optical_spec"]
        wvl = sm.central_wavelength()
        radius = osp.pupil.value / 2.0
        sm.gaps[0].thi = 0.0
        try:
            opm.update_model()
        except ZeroDivisionError:
            # The paraxial update divides by the object-to-pupil distance, 0 when surface 1 is
            # the stop; the trace reads the gap directly.
            pass
        # A file without a stop has it on surface 1, as lensbake reads it.
        stop = sm.stop_surface if sm.stop_surface is not None else 1

        def path(x, y, d):
            return trace(sm, np.array([x, y, 0.0]), d, wvl)[0]

        fields = []
        for fld in osp.field_of_view.fields:
            d = np.array([np.tan(np.radians(fld.x)), np.tan(np.radians(fld.y)), 1.0])
            d /= np.linalg.norm(d)
            start = np.zeros(2)
            for _ in range(50):
                miss = path(*start, d)[stop][0][:2]
                if np.hypot(*miss) < 1e-12:
                    break
                h = 1e-6 * radius
                jac = np.column_stack([
                    (path(start[0] + h, start[1], d)[stop][0][:2] - miss) / h,
                    (path(start[0], start[1] + h, d)[stop][0][:2] - miss) / h,
                ])
                start = start - np.linalg.solve(jac, miss)
            chief = path(*start, d)[-1][0]

            def error(u, v):
                q = path(start[0] + u * radius, start[1] + v * radius, d)[-1][0]
                return [float(q[0] - chief[0]), float(q[1] - chief[1])]

            fields.append({
                "field_deg": [fld.x, fld.y],
                "chief": [float(chief[0]), float(chief[1])],
                "tangential": [error(0.0, p) for p in PUPIL],
                "sagittal": [error(p, 0.0) for p in PUPIL],
            })
        out[name] = {"wavelength_nm": wvl, "pupil": PUPIL, "fields": fields}
    with open(CORPUS + "analyze_placed_peers.json", "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
