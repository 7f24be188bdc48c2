"""Writes tests/data/odd_asphere_peer.json: where optiland traces chosen rays through the two
odd-asphere test lenses (tests/data/odd_asphere_singlet.zmx, and odd_asphere_cone.zmx, the same
lens with a cone term r on its second face), for tests/odd_asphere.rs.

Each ray starts at (x, y, 0) on the plane of the first vertex along (tan_x, tan_y, 1) normalised
and is traced to the image plane (80 mm behind the last vertex); the result is the point there.
optiland reads PARM 1..8 of TYPE ODDASPHE as the coefficients on r .. r^8, as OpticStudio
defines them.

Also recorded: a ray 1e-4 mm above the axis through the singlet, whose angle after the lens
gives the focal length the exact trace has in the paraxial limit (optiland's own paraxial trace
takes the vertex curvature from CURV alone, leaving out the r^2 term PARM 2 adds).

Run from the repository root with optiland 0.6.3 installed:
    python tools/odd_asphere_peer.py
"""
import json
import warnings

import numpy as np
from optiland.fileio import load_zemax_file
from optiland.rays import RealRays

warnings.filterwarnings("ignore")

WAVELENGTH_UM = 0.5875618
RAYS = [
    [0.0, 0.0, 0.0, 0.0],
    [3.0, 4.0, 0.0, 0.0],
    [-5.0, 2.0, 0.01, 0.02],
    [7.0, -6.0, -0.02, 0.01],
    [0.0, 9.5, 0.0, -0.03],
    [0.4, -0.3, 0.05, 0.0],
]


def trace(optic, rays):
    # optiland stops its Newton search at a sag residual of 1e-10 mm by default, which moves
    # image points by as much; these rays converge far below it.
    for surface in optic.surface_group.surfaces:
        if hasattr(surface.geometry, "tol"):
            surface.geometry.tol = 1e-15
    x, y, tx, ty = (np.array(c, dtype=float) for c in zip(*rays))
    d = np.stack([tx, ty, np.ones_like(tx)])
    d /= np.linalg.norm(d, axis=0)
    n = len(rays)
    real = RealRays(x, y, np.zeros(n), d[0], d[1], d[2], np.ones(n), np.full(n, WAVELENGTH_UM))
    optic.surface_group.trace(real)
    group = optic.surface_group
    return group, [
        [float(group.x[-1][k]), float(group.y[-1][k]), float(group.z[-1][k])] for k in range(n)
    ]


def main():
    out = {"source": "optiland 0.6.3 (tools/odd_asphere_peer.py)", "lenses": {}}
    for name in ["odd_asphere_singlet.zmx", "odd_asphere_cone.zmx"]:
        optic = load_zemax_file("tests/data/" + name)
        _, image = trace(optic, RAYS)
        out["lenses"][name] = {"rays": RAYS, "image_points": image}
    optic = load_zemax_file("tests/data/odd_asphere_singlet.zmx")
    height = 1e-4
    group, _ = trace(optic, [[0.0, height, 0.0, 0.0]])
    slope = float(group.M[-1][0] / group.N[-1][0])
    # The glass's index as optiland computes it (its data set is not lensbake's).
    material = optic.surface_group.surfaces[1].material_post
    out["glass_index"] = float(np.ravel(material.n(WAVELENGTH_UM))[0])
    out["near_axis_focal_length"] = {"height": height, "value": -height / slope}
    with open("tests/data/odd_asphere_peer.json", "w") as f:
        json.dump(out, f)
        f.write("\n")


main()
