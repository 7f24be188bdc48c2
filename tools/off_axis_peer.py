"""Writes tests/data/corpus/off_axis_peers.json: where rayoptics traces chosen rays of the corpus
files that tilt or decentre surfaces off one axis, for tests/off_axis.rs.

Each ray starts at (x, y, 0) in the frame of surface 1 before any decentre (the object side's
axis is z) along (tan_x, tan_y, 1) normalised; the object gap is set to 0 so that rayoptics'
object plane is that z = 0 plane. The result is where the ray meets the image plane, in the
image plane's own frame (mm).

rayoptics 0.9.8 cannot build its model of the optiland file (its part tree's parser fails), and
for the two four-mirror telescopes its rays off the meridian land up to 8e-4 mm from where
optiland and lensbake put them (they agree to 1e-12), so optiland 0.6.3 traces those three; its result is the global point on the image plane ("global"),
and "glass_indices" gives the index optiland uses after each of its surfaces that is glass (its
surface numbers, which count a coordinate break with the surface it moves).

Run from the repository root with rayoptics 0.9.8 and optiland 0.6.3 installed:
    python tools/off_axis_peer.py
"""
import json
import os
import tempfile
import warnings

import numpy as np
from rayoptics.environment import open_model
from rayoptics.raytr.trace import trace

warnings.filterwarnings("ignore")

CORPUS = "tests/data/corpus/"
RAYS = {
    "rayoptics__tilt_test.seq": [
        [0, 0, 0, 0], [30, -20, 0, 0.001], [-40, 10, 0.01, -0.02],
    ],
    # Near the chief rays, which enter 113-178 mm above the axis to pass the off-axis segments.
    "rayoptics__threemir.seq": [
        [0, 145, 0, 0], [10, 140, 0, 0.001], [-10, 150, 0.002, -0.003], [-31, 113, 0.0349, 0.0349],
    ],
}
OPTILAND_RAYS = {
    "rayoptics__HoO-V2C18Ex66.zmx": [
        [0, 0, 0, 0], [3, 4, 0, 0], [-5, 2, 0.01, 0.02], [6, -6, -0.1, 0.05], [0, 8, 0.15, 0],
    ],
    "rayoptics__HoO-V2C18Ex66NEW.zmx": [
        [0, 0, 0, 0], [3, 4, 0, 0], [-5, 2, 0.01, 0.02], [6, -6, -0.1, 0.05], [0, 8, 0.15, 0],
    ],
    "optiland__complicated_fold_mirrors_setup_v2.zmx": [
        [0, 0, 0, 0], [5, -3, 0, 0], [-6, 2, 0.01, 0.01], [2, 7, -0.02, 0.005],
    ],
}


def image_point(sm, wvl, x, y, tx, ty):
    d = np.array([tx, ty, 1.0])
    d /= np.linalg.norm(d)
    segments = trace(sm, np.array([x, y, 0.0]), d, wvl)[0]
    point = segments[-1][0]
    return [float(point[0]), float(point[1])]


def readable_copy(path):
    """The file itself, or a UTF-8 copy of a UTF-16 one (rayoptics 0.9.8 reads only 8-bit text)."""
    raw = open(path, "rb").read()
    if not raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        return path
    copy = os.path.join(tempfile.mkdtemp(), os.path.basename(path))
    with open(copy, "w", encoding="utf-8") as f:
        f.write(raw.decode("utf-16"))
    return copy


def optiland_points(name, rays):
    from optiland.fileio import load_zemax_file
    from optiland.rays import RealRays

    optic = load_zemax_file(CORPUS + name)
    wavelength_um = optic.primary_wavelength
    # optiland reads BK7 from another data set than lensbake (its n(550 nm) differs by 7e-4);
    # the test gives lensbake the peer's indices, so the rays compare the geometry alone.
    indices = {
        str(k): float(np.ravel(s.material_post.n(wavelength_um))[0])
        for k, s in enumerate(optic.surface_group.surfaces)
        if type(s.material_post).__name__ == "Material"
    }
    points = []
    for x, y, tx, ty in rays:
        d = np.array([tx, ty, 1.0])
        d /= np.linalg.norm(d)
        one = lambda v: np.array([float(v)])
        bundle = RealRays(one(x), one(y), one(0), one(d[0]), one(d[1]), one(d[2]), one(1),
                          one(wavelength_um))
        optic.surface_group.trace(bundle, skip=1)
        group = optic.surface_group
        points.append([float(group.x[-1][0]), float(group.y[-1][0]), float(group.z[-1][0])])
    return {
        "wavelength_nm": wavelength_um * 1000.0,
        "rays": rays,
        "global": points,
        "glass_indices": indices,
    }


def main():
    out = {}
    for name, rays in RAYS.items():
        opm = open_model(readable_copy(CORPUS + name))
        sm = opm["seq_model"]
        wvl = sm.central_wavelength()
        sm.gaps[0].thi = 0.0
        try:
            opm.update_model()
        except ZeroDivisionError:
            # The paraxial update divides by the object-to-pupil distance, 0 when surface 1 is
            # the stop; the trace reads the gap directly.
            pass
        out[name] = {
            "wavelength_nm": wvl,
            "rays": rays,
            "image": [image_point(sm, wvl, *ray) for ray in rays],
        }
    for name, rays in OPTILAND_RAYS.items():
        out[name] = optiland_points(name, rays)
    with open(CORPUS + "off_axis_peers.json", "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
