"""Side-by-side exact trace: optiland 0.6.3 (NumPy) and lensbake, same lens, same ray bundle.

Run through run.sh, which creates the virtual environment. Steps:
1. The lens is an oracle table (constant indices): written as a lensbake RON file and built as an
   optiland Optic with ideal materials and radial clear apertures.
2. The ray bundle is the one `lensbake bench trace` draws: collimated beams, field angle uniform
   over [0, traceable field] in the y-z plane, pupil point uniform over the paraxial entrance
   pupil, rays starting one semi-aperture plus 1 mm before surface 1. The traceable field and
   the pupil are the oracle's (lensbake's own agree with them, see tests/trace_aim.rs).
3. Agreement: a sample of rays goes through `lensbake trace --json` and through optiland; the
   status must agree ray by ray and the ray after the last surface within 1e-9 mm / 1e-12.
4. Throughput: optiland's NumPy trace of N rays against `lensbake bench trace` of N rays on one
   thread and on all cores, repeated, medians compared as rays per second (optiland traces
   clipped rays to the end, lensbake stops them at the vignetting surface; ray-surface counts
   are printed too). lensbake's time is its second trace of the rays, into the storage its
   first trace (into new storage, printed too) allocated.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from optiland.materials import IdealMaterial
from optiland.optic import Optic
from optiland.physical_apertures import RadialAperture
from optiland.rays import RealRays

POSITION_TOLERANCE_MM = 1e-9
DIRECTION_TOLERANCE = 1e-12
WAVELENGTH_UM = 0.5875618


def oracle_dir():
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "tests", "data", "truth", "oracle"))


def ron_prescription(lens):
    table = lens["prescription"]
    rows = []
    for s in table["surfaces"]:
        shape = "Plane" if s["curvature"] == 0 else f"Sphere(curvature: {s['curvature']!r})"
        stop = "Some(Circle)" if s["stop"] else "None"
        rows.append(
            f"    (shape: {shape}, thickness: {s['thickness']!r}, medium: Index({s['n']!r}), "
            f"semi_aperture: {s['semi_aperture']!r}, stop: {stop}),"
        )
    return (
        f'(provenance: (title: "{lens["name"]}", design_wavelength_nm: Some({lens["wavelength_nm"]!r})),\n'
        f" object_medium: Index({table['object_space_index']!r}),\n surfaces: [\n"
        + "\n".join(rows)
        + "\n])\n"
    )


def optiland_lens(lens):
    table = lens["prescription"]
    optic = Optic()
    optic.surfaces.add(index=0, radius=np.inf, thickness=np.inf,
                       material=IdealMaterial(table["object_space_index"]))
    for k, s in enumerate(table["surfaces"], start=1):
        radius = np.inf if s["curvature"] == 0 else 1.0 / s["curvature"]
        optic.surfaces.add(index=k, radius=radius, thickness=s["thickness"],
                           material=IdealMaterial(s["n"]), is_stop=s["stop"],
                           aperture=RadialAperture(r_max=s["semi_aperture"]))
    optic.surfaces.add(index=len(table["surfaces"]) + 1)
    optic.set_aperture(aperture_type="EPD", value=lens["system"]["epd_used"])
    optic.fields.set_type("angle")
    optic.fields.add(y=0.0)
    optic.wavelengths.add(value=WAVELENGTH_UM, is_primary=True)
    return optic


def bundle(lens, n, seed):
    quick = lens["quick_reference"]
    field_deg = lens["infinite_conjugate"]["max_field_with_traceable_chief_ray"]["with_apertures"]["last_ok_deg"]
    pupil_z, pupil_r = quick["z_entrance_pupil"], 0.5 * quick["epd"]
    first = lens["prescription"]["surfaces"][0]
    start_z = first["vertex_z"] - first["semi_aperture"] - 1.0
    rng = np.random.default_rng(seed)
    field = np.radians(rng.uniform(0.0, field_deg, n))
    radius = pupil_r * np.sqrt(rng.uniform(0.0, 1.0, n))
    azimuth = rng.uniform(0.0, 2.0 * np.pi, n)
    M, N = np.sin(field), np.cos(field)
    back = (pupil_z - start_z) / N
    x = radius * np.cos(azimuth)
    y = radius * np.sin(azimuth) - back * M
    return x, y, np.full(n, start_z), np.zeros(n), M, N, field_deg, (pupil_z, pupil_r)


def optiland_trace(optic, rays, record):
    x, y, z, L, M, N = rays
    real = RealRays(x.copy(), y.copy(), z.copy(), L.copy(), M.copy(), N.copy(),
                    np.ones_like(x), np.full_like(x, WAVELENGTH_UM))
    start = time.perf_counter()
    optic.surfaces.trace(real, skip=1, record=record)
    return time.perf_counter() - start


def lensbake(binary, *args, stdin=None):
    out = subprocess.run([binary, *args], input=stdin, capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def check_agreement(binary, ron, optic, rays, n_surfaces):
    """Statuses and the ray leaving the last surface, ray by ray."""
    x, y, z, L, M, N = rays
    payload = json.dumps([{"origin": [x[i], y[i], z[i]], "direction": [L[i], M[i], N[i]]}
                          for i in range(len(x))])
    ours = lensbake(binary, "trace", ron, "--rays", "-", "--json", stdin=payload)
    optiland_trace(optic, rays, record=True)
    group = optic.surfaces
    last = n_surfaces - 1  # with skip=1 optiland records surfaces 1..N+1 at indices 0..N
    gx, gy, gz = group.x[last], group.y[last], group.z[last]
    gL, gM, gN = group.L[last], group.M[last], group.N[last]
    alive = np.isfinite(gx) & np.isfinite(gL)
    # optiland clips by zeroing intensity; a ray is unclipped when every surface kept it.
    unclipped = alive & np.all(group.intensity[:last + 1] > 0, axis=0)
    worst_p = worst_d = 0.0
    mismatches = 0
    counts = {}
    for i, r in enumerate(ours):
        counts[r["status"]] = counts.get(r["status"], 0) + 1
        if (r["status"] == "ok") != bool(unclipped[i]):
            mismatches += 1
            continue
        if r["status"] == "ok":
            worst_p = max(worst_p, *(abs(a - b) for a, b in zip(r["position"], (gx[i], gy[i], gz[i]))))
            worst_d = max(worst_d, *(abs(a - b) for a, b in zip(r["direction"], (gL[i], gM[i], gN[i]))))
    return counts, mismatches, worst_p, worst_d


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--lensbake", required=True)
    parser.add_argument("--lens", default="pbrt_dgauss_50mm")
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--sample", type=int, default=5000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    with open(os.path.join(oracle_dir(), args.lens + ".json")) as f:
        lens = json.load(f)["lenses"][0]
    n_surfaces = len(lens["prescription"]["surfaces"])
    optic = optiland_lens(lens)
    with tempfile.TemporaryDirectory() as tmp:
        ron = os.path.join(tmp, args.lens + ".ron")
        with open(ron, "w") as f:
            f.write(ron_prescription(lens))

        *sample, field_deg, (pupil_z, pupil_r) = bundle(lens, args.sample, seed=1)
        print(f"lens {args.lens}: {n_surfaces} surfaces; bundle: field 0..{field_deg} deg, "
              f"entrance pupil radius {pupil_r:.6f} mm at z = {pupil_z:.6f} mm")
        counts, mismatches, worst_p, worst_d = check_agreement(args.lensbake, ron, optic, sample, n_surfaces)
        print(f"agreement on {args.sample} rays: statuses {counts}, {mismatches} status mismatches; "
              f"ok rays after surface {n_surfaces}: max |dp| = {worst_p:.2e} mm, max |dd| = {worst_d:.2e}")
        agree = mismatches == 0 and worst_p <= POSITION_TOLERANCE_MM and worst_d <= DIRECTION_TOLERANCE

        *rays, _, _ = bundle(lens, args.rays, seed=2)
        # optiland compiles its intersection kernels with numba on first use: keep that out.
        optiland_trace(optic, bundle(lens, 10_000, seed=3)[:6], record=False)
        timings = {"optiland": [], "lensbake_1": [], "lensbake_1_new_output": [], "lensbake_all": []}
        ray_surfaces = None
        for _ in range(args.repeats):
            timings["optiland"].append(optiland_trace(optic, rays, record=False))
            for key, extra in (("lensbake_1", ["--threads", "1"]), ("lensbake_all", [])):
                out = lensbake(args.lensbake, "bench", "trace", ron, "--rays", str(args.rays), "--json", *extra)
                timings[key].append(out["seconds"])
                if key == "lensbake_1":
                    timings["lensbake_1_new_output"].append(out["seconds_new_output"])
                ray_surfaces = out["ray_surfaces"]

    median = {k: statistics.median(v) for k, v in timings.items()}
    rate = {k: args.rays / s for k, s in median.items()}
    print(f"{args.rays} rays, median of {args.repeats} runs (all runs: "
          + ", ".join(f"{k} {['%.3f' % s for s in v]}" for k, v in timings.items()) + " s)")
    print(f"  optiland (NumPy)     {median['optiland']:.4f} s  {rate['optiland'] / 1e6:8.3f} M rays/s"
          f"  ({args.rays * (n_surfaces + 1) / median['optiland'] / 1e6:.1f} M ray-surfaces/s incl. image plane)")
    for key, name in (("lensbake_1", "lensbake 1 thread "), ("lensbake_1_new_output", "  into new storage"),
                      ("lensbake_all", "lensbake all cores")):
        print(f"  {name}   {median[key]:.4f} s  {rate[key] / 1e6:8.3f} M rays/s"
              f"  ({ray_surfaces / median[key] / 1e6:.1f} M ray-surfaces/s computed)")
    print(f"throughput ratio lensbake/optiland: {rate['lensbake_1'] / rate['optiland']:.1f}x on one thread "
          f"({rate['lensbake_1_new_output'] / rate['optiland']:.1f}x into new storage), "
          f"{rate['lensbake_all'] / rate['optiland']:.1f}x on all cores")
    if not agree:
        print("DISAGREEMENT between lensbake and optiland", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
