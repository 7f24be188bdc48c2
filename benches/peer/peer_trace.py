"""Side-by-side exact trace: optiland 0.6.3 (NumPy) and lensbake, same lens, same ray bundle.

Run through run.sh, which creates the virtual environment. Steps:
1. The lens is an oracle table (`--lens NAME` with tests/data/truth/oracle/NAME.json, constant
   indices), or any lens lensbake reads (a bundled name or a file) whose surfaces are planes,
   spheres, conics, even aspheres (optiland's `even_asphere`, coefficients on r^2, r^4, ... as
   lensbake's) or ideal lenses (optiland's `paraxial`), refracting or mirrors, with circular
   stops and central obscurations allowed;
   `lensbake lens convert --indices-at-nm` gives each of its media (a catalogue glass, a
   dispersion formula, a model glass, a table) its index at the d line. Either is written as a
   lensbake RON file of constant indices and built as an optiland Optic with ideal materials,
   optiland's mirrors and radial clear apertures (inner radius: the obscuration).
2. The ray bundle is the one `lensbake bench trace` draws: collimated beams, field angle uniform
   over [0, traceable field] in the y-z plane, pupil point uniform over the paraxial entrance
   pupil, rays starting one semi-aperture plus 1 mm before surface 1. The traceable field and
   the pupil are the oracle's (lensbake's own agree with them, see tests/trace_aim.rs) or, for
   a lens without an oracle, the ones `lensbake bench trace --json` reports.
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
import re
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
# optiland's Newton search for an asphere stops at a sag residual of 1e-6 mm unless told; lensbake
# converges to rounding, and the rays are compared to 1e-9 mm.
ASPHERE_TOLERANCE_MM = 1e-12


def oracle_dir():
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "tests", "data", "truth", "oracle"))


class Bundle:
    """The ray bundle `lensbake bench trace` draws: field angles uniform over [0, field_deg] in
    the y-z plane, pupil points uniform over the paraxial entrance pupil, rays starting on the
    plane z = start_z."""

    def __init__(self, field_deg, pupil_z, pupil_diameter, start_z):
        self.field_deg, self.pupil_z = field_deg, pupil_z
        self.pupil_diameter, self.start_z = pupil_diameter, start_z

    @staticmethod
    def from_lensbake(binary, ron):
        """The bundle lensbake draws for the lens in the file `ron`."""
        bundle = lensbake(binary, "bench", "trace", ron, "--rays", "1", "--json")["bundle"]
        return Bundle(bundle["max_field_deg"], bundle["entrance_pupil_z"],
                      bundle["entrance_pupil_diameter"], bundle["start_z"])

    def sample(self, n, seed):
        pupil_r = 0.5 * self.pupil_diameter
        rng = np.random.default_rng(seed)
        field = np.radians(rng.uniform(0.0, self.field_deg, n))
        radius = pupil_r * np.sqrt(rng.uniform(0.0, 1.0, n))
        azimuth = rng.uniform(0.0, 2.0 * np.pi, n)
        M, N = np.sin(field), np.cos(field)
        back = (self.pupil_z - self.start_z) / N
        x = radius * np.cos(azimuth)
        y = radius * np.sin(azimuth) - back * M
        return x, y, np.full(n, self.start_z), np.zeros(n), M, N


class Lens:
    """A lens of constant indices, as both programs are given it: each surface's curvature, conic
    constant, even aspheric coefficients (on r^2, r^4, ...), thickness, index after it, clear
    semi-aperture and whether it is the stop."""

    def __init__(self, name, object_index, surfaces):
        self.name, self.object_index, self.surfaces = name, object_index, surfaces

    @staticmethod
    def from_oracle(name):
        """The oracle's lens and the bundle drawn from its own pupil and traceable field."""
        with open(os.path.join(oracle_dir(), name + ".json")) as f:
            lens = json.load(f)["lenses"][0]
        table = lens["prescription"]
        surfaces = [dict(curvature=s["curvature"], conic=0.0, coefficients=[], focal_length=None,
                         thickness=s["thickness"], n=s["n"], semi_aperture=s["semi_aperture"],
                         stop=s["stop"], obscuration=0.0) for s in table["surfaces"]]
        quick = lens["quick_reference"]
        field = lens["infinite_conjugate"]["max_field_with_traceable_chief_ray"]["with_apertures"]
        first = table["surfaces"][0]
        bundle = Bundle(field["last_ok_deg"], quick["z_entrance_pupil"], quick["epd"],
                        first["vertex_z"] - first["semi_aperture"] - 1.0)
        return Lens(lens["name"], table["object_space_index"], surfaces), bundle

    @staticmethod
    def from_lensbake(binary, spec, tmp):
        """`spec` read by lensbake, written out as its RON with each medium's index at the d line
        and read back here."""
        path = os.path.join(tmp, "source.ron")
        run_lensbake(binary, "lens", "convert", spec, path,
                     "--indices-at-nm", f"{WAVELENGTH_UM * 1e3:.4f}")
        with open(path) as f:
            table = parse_ron(f.read())
        surfaces = [lensbake_surface(k + 1, s) for k, s in enumerate(table["surfaces"])]
        return Lens(spec, constant_index("object_medium", table["object_medium"]), surfaces)

    def ron(self):
        rows = []
        for s in self.surfaces:
            if s["focal_length"] is not None:
                shape = f"IdealLens(focal_length: {s['focal_length']!r})"
            elif s["coefficients"]:
                terms = ", ".join(repr(a) for a in s["coefficients"])
                shape = (f"EvenAsphere(curvature: {s['curvature']!r}, conic: {s['conic']!r}, "
                         f"coefficients: [{terms}])")
            elif s["conic"] != 0.0:
                shape = f"Conic(curvature: {s['curvature']!r}, conic: {s['conic']!r})"
            elif s["curvature"] == 0.0:
                shape = "Plane"
            else:
                shape = f"Sphere(curvature: {s['curvature']!r})"
            stop = "Some(Circle)" if s["stop"] else "None"
            medium = "Mirror" if s["n"] is None else f"Index({s['n']!r})"
            obscuration = f"Some({s['obscuration']!r})" if s["obscuration"] else "None"
            rows.append(
                f"    (shape: {shape}, thickness: {s['thickness']!r}, medium: {medium}, "
                f"semi_aperture: {s['semi_aperture']!r}, stop: {stop}, obscuration: {obscuration}),"
            )
        return (
            f'(provenance: (title: "{self.name}", design_wavelength_nm: Some({WAVELENGTH_UM * 1e3:.4f})),\n'
            f" object_medium: Index({self.object_index!r}),\n surfaces: [\n"
            + "\n".join(rows)
            + "\n])\n"
        )

    def optic(self, epd):
        optic = Optic()
        optic.surfaces.add(index=0, radius=np.inf, thickness=np.inf,
                           material=IdealMaterial(self.object_index))
        for k, s in enumerate(self.surfaces, start=1):
            radius = np.inf if s["curvature"] == 0 else 1.0 / s["curvature"]
            shape = {"conic": s["conic"]}
            if s["focal_length"] is not None:
                # optiland's paraxial surface: a plane whose thin-lens deflection (tangents less
                # the height over f) is lensbake's ideal lens in air.
                shape = dict(surface_type="paraxial", f=s["focal_length"])
            elif s["coefficients"]:
                shape.update(surface_type="even_asphere", coefficients=list(s["coefficients"]),
                             tol=ASPHERE_TOLERANCE_MM)
            # A mirror's material is "mirror": optiland keeps the medium before it after it.
            material = "mirror" if s["n"] is None else IdealMaterial(s["n"])
            aperture = RadialAperture(r_max=s["semi_aperture"], r_min=s["obscuration"])
            optic.surfaces.add(index=k, radius=radius, thickness=s["thickness"],
                               material=material, is_stop=s["stop"], aperture=aperture, **shape)
        optic.surfaces.add(index=len(self.surfaces) + 1)
        optic.set_aperture(aperture_type="EPD", value=epd)
        optic.fields.set_type("angle")
        optic.fields.add(y=0.0)
        optic.wavelengths.add(value=WAVELENGTH_UM, is_primary=True)
        return optic


def parse_ron(text):
    """The subset of RON lensbake writes: structs and tuples `(...)` (named fields become a dict,
    an enum variant `Name(...)` a dict with its name under "variant"), lists, strings, numbers,
    bare names (`None`, `Air`, `Circle`)."""
    tokens = re.findall(r'"(?:[^"\\]|\\.)*"|[A-Za-z_][A-Za-z0-9_]*|[-+0-9.eE]+|[()\[\]:,]', text)
    position = 0

    def value():
        nonlocal position
        token = tokens[position]
        position += 1
        if token == "[":
            items = []
            while tokens[position] != "]":
                items.append(value())
                if tokens[position] == ",":
                    position += 1
            position += 1
            return items
        if token == "(":
            return group(None)
        if token.startswith('"'):
            return json.loads(token)
        if re.match(r"[A-Za-z_]", token):
            if position < len(tokens) and tokens[position] == "(":
                position += 1
                return group(token)
            return {"variant": token}
        return float(token)

    def group(variant):
        nonlocal position
        fields, items = {}, []
        while tokens[position] != ")":
            if tokens[position + 1] == ":" and re.match(r"[A-Za-z_]", tokens[position]):
                key = tokens[position]
                position += 2
                fields[key] = value()
            else:
                items.append(value())
            if tokens[position] == ",":
                position += 1
        position += 1
        if variant is not None:
            fields["variant"] = variant
            if items:
                fields["items"] = items
        return fields

    return value()


def constant_index(where, medium):
    """The index of a medium lensbake wrote at the d line."""
    kind = medium["variant"]
    if kind == "Air":
        return 1.0
    if kind == "Index":
        return medium["items"][0]
    sys.exit(f"error: {where}: medium {kind} has no constant index")


def lensbake_surface(number, surface):
    shape = surface["shape"]
    kind = shape["variant"]
    if kind not in ("Plane", "Sphere", "Conic", "EvenAsphere", "IdealLens"):
        sys.exit(f"error: surface {number}: shape {kind} is not one optiland is built with here "
                 "(planes, spheres, conics, even aspheres and ideal lenses are)")
    stop = surface["stop"]
    is_stop = stop["variant"] == "Some"
    obscuration = surface.get("obscuration", {"variant": "None"})
    if is_stop and stop["items"][0]["variant"] != "Circle":
        sys.exit(f"error: surface {number}: only a circular stop is built here")
    mirror = surface["medium"]["variant"] == "Mirror"
    return dict(curvature=shape.get("curvature", 0.0), conic=shape.get("conic", 0.0),
                coefficients=shape.get("coefficients", []),
                focal_length=shape.get("focal_length"), thickness=surface["thickness"],
                n=None if mirror else constant_index(f"surface {number}", surface["medium"]),
                semi_aperture=surface["semi_aperture"], stop=is_stop,
                obscuration=obscuration["items"][0] if obscuration["variant"] == "Some" else 0.0)


def optiland_trace(optic, rays, record):
    x, y, z, L, M, N = rays
    real = RealRays(x.copy(), y.copy(), z.copy(), L.copy(), M.copy(), N.copy(),
                    np.ones_like(x), np.full_like(x, WAVELENGTH_UM))
    start = time.perf_counter()
    optic.surfaces.trace(real, skip=1, record=record)
    return time.perf_counter() - start


def run_lensbake(binary, *args, stdin=None):
    """lensbake's standard output; its error line, and exit, where it fails."""
    out = subprocess.run([binary, *args], input=stdin, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(out.stderr.strip() or f"error: lensbake {' '.join(args)} failed")
    return out.stdout


def lensbake(binary, *args, stdin=None):
    return json.loads(run_lensbake(binary, *args, stdin=stdin))


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

    with tempfile.TemporaryDirectory() as tmp:
        if os.path.exists(os.path.join(oracle_dir(), args.lens + ".json")):
            lens, bundle = Lens.from_oracle(args.lens)
        else:
            lens, bundle = Lens.from_lensbake(args.lensbake, args.lens, tmp), None
        ron = os.path.join(tmp, "lens.ron")
        with open(ron, "w") as f:
            f.write(lens.ron())
        bundle = bundle or Bundle.from_lensbake(args.lensbake, ron)
        n_surfaces = len(lens.surfaces)
        optic = lens.optic(bundle.pupil_diameter)

        sample = bundle.sample(args.sample, seed=1)
        print(f"lens {args.lens}: {n_surfaces} surfaces; bundle: field 0..{bundle.field_deg} deg, "
              f"entrance pupil radius {0.5 * bundle.pupil_diameter:.6f} mm at z = {bundle.pupil_z:.6f} mm")
        counts, mismatches, worst_p, worst_d = check_agreement(args.lensbake, ron, optic, sample, n_surfaces)
        print(f"agreement on {args.sample} rays: statuses {counts}, {mismatches} status mismatches; "
              f"ok rays after surface {n_surfaces}: max |dp| = {worst_p:.2e} mm, max |dd| = {worst_d:.2e}")
        agree = mismatches == 0 and worst_p <= POSITION_TOLERANCE_MM and worst_d <= DIRECTION_TOLERANCE

        rays = bundle.sample(args.rays, seed=2)
        # optiland compiles its intersection kernels with numba on first use: keep that out.
        optiland_trace(optic, bundle.sample(10_000, seed=3), record=False)
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
