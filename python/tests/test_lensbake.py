"""The Python package against the library's own truths and the command line's JSON.

The command line comes from LENSBAKE_CLI, else target/release/lensbake of this repository.
"""

import json
import math
import re
import os
import pathlib
import subprocess

import numpy as np
import pytest

import lensbake

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = pathlib.Path(os.environ.get("LENSBAKE_CLI", REPO / "target" / "release" / "lensbake"))
ZEMAX_TRIPLET = str(REPO / "examples" / "lenses" / "cooke_triplet.zmx")


def cli_json(*args):
    if not CLI.exists():
        pytest.fail(f"{CLI} is missing: build it (cargo build --release --locked) or set LENSBAKE_CLI")
    done = subprocess.run([str(CLI), *args], capture_output=True, text=True, check=True)
    return json.loads(done.stdout)


def cli_error(*args):
    done = subprocess.run([str(CLI), *args], capture_output=True, text=True)
    assert done.returncode == 2, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, done.stderr
    return errors[0][len("error: "):]


@pytest.fixture(scope="module")
def dgauss():
    return lensbake.load_lens("dgauss-50mm")


@pytest.fixture(scope="module")
def table(dgauss):
    return lensbake.bake(dgauss, 16)


# -- loading -----------------------------------------------------------------------------------


def test_load_bundled_and_file(dgauss):
    assert dgauss.name == "dgauss-50mm"
    assert isinstance(dgauss.title, str) and dgauss.title
    triplet = lensbake.load_lens(ZEMAX_TRIPLET)
    assert len(triplet.surfaces) == 6
    assert triplet.surfaces == lensbake.load_lens(ZEMAX_TRIPLET, format="zemax").surfaces
    assert "dgauss-50mm" in repr(dgauss)
    assert 380.0 < dgauss.design_wavelength_nm < 780.0


def test_unknown_lens_is_the_cli_message():
    with pytest.raises(lensbake.LensbakeError) as caught:
        lensbake.load_lens("no-such-lens")
    assert str(caught.value) in cli_error("analyze", "no-such-lens")
    assert isinstance(caught.value, ValueError)


def test_broken_lens_file_is_located(tmp_path):
    broken = tmp_path / "broken.zmx"
    text = pathlib.Path(ZEMAX_TRIPLET).read_text(errors="replace")
    broken.write_text(text.replace("CURV", "CURV not-a-number", 1))
    with pytest.raises(lensbake.LensbakeError) as caught:
        lensbake.load_lens(str(broken))
    message = str(caught.value)
    assert re.search(r"broken\.zmx:\d+, field `CURV`", message), message
    assert message == cli_error("analyze", str(broken))


def test_unknown_format_is_refused():
    with pytest.raises(lensbake.LensbakeError, match="format must be one of"):
        lensbake.load_lens(ZEMAX_TRIPLET, format="docx")


def test_conditions_and_surfaces_are_plain_data(dgauss):
    conditions = dgauss.conditions
    assert conditions == dgauss.analyze()["conditions"]
    json.dumps(conditions)
    json.dumps(dgauss.surfaces)


def test_convert_round_trips(dgauss, tmp_path):
    for name in ["copy.ron", "copy.zmx", "copy.dat"]:
        dgauss.convert(tmp_path / name)
        again = lensbake.load_lens(str(tmp_path / name))
        assert len(again.surfaces) == len(dgauss.surfaces)
        efl = again.analyze()["first_order"]["efl"]
        assert efl == pytest.approx(dgauss.analyze()["first_order"]["efl"], rel=1e-6)
    with pytest.raises(lensbake.LensbakeError, match="the output must be"):
        dgauss.convert(tmp_path / "copy.txt")
    assert not (tmp_path / "copy.txt").exists()


# -- analysis ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["dgauss-50mm", "cooke-triplet", "tessar", ZEMAX_TRIPLET])
def test_analyze_equals_the_cli_json(name):
    assert lensbake.load_lens(name).analyze() == cli_json("analyze", name, "--json")


def test_analyze_options_equal_the_cli(dgauss):
    python = dgauss.analyze(field_deg=10.0, epd_mm=12.5, object_distance_mm=3000.0, wavelength_nm=486.13)
    cli = cli_json(
        "analyze", "dgauss-50mm", "--field-deg", "10", "--epd-mm", "12.5",
        "--object-distance-mm", "3000", "--wavelength-nm", "486.13", "--json",
    )
    assert python == cli
    # f-number = EFL / EPD by definition.
    first = python["first_order"]
    assert first["f_number"] == pytest.approx(first["efl"] / 12.5, rel=1e-12)


def test_analyze_bad_input_raises(dgauss):
    with pytest.raises(lensbake.LensbakeError):
        dgauss.analyze(epd_mm=float("nan"))
    with pytest.raises(lensbake.LensbakeError, match="ray_aiming"):
        dgauss.analyze(ray_aiming="sideways")


# -- trace -------------------------------------------------------------------------------------


def fan(count, height):
    origins = np.zeros((count, 3))
    origins[:, 1] = np.linspace(-height, height, count)
    origins[:, 2] = -20.0
    directions = np.tile([0.0, 0.0, 1.0], (count, 1))
    return origins, directions


def test_trace_shapes_dtypes_and_codes(dgauss):
    origins, directions = fan(101, 40.0)
    positions, headings, outcome, surface = dgauss.trace(origins, directions)
    assert positions.shape == headings.shape == (101, 3)
    assert positions.dtype == headings.dtype == np.float64
    assert outcome.shape == surface.shape == (101,)
    assert outcome.dtype == np.uint8 and surface.dtype == np.uint32
    assert np.isfinite(positions).all() and np.isfinite(headings).all()
    ok = outcome == lensbake.OUTCOME_OK
    assert ok[50] and not ok[0]
    assert (surface[ok] == 0).all() and (surface[~ok] >= 1).all()
    assert np.allclose(np.linalg.norm(headings[ok], axis=1), 1.0, atol=1e-12)
    # Apertures off: the 40 mm rays cross every surface too, or fail only geometrically.
    _, _, unapertured, _ = dgauss.trace(origins, directions, apertures=False)
    assert (unapertured != lensbake.OUTCOME_VIGNETTED).all()


def test_trace_takes_lists_and_other_dtypes(dgauss):
    origins, directions = fan(5, 5.0)
    from_lists = dgauss.trace(origins.tolist(), directions.astype(np.float32))
    from_arrays = dgauss.trace(origins, directions)
    for a, b in zip(from_lists, from_arrays):
        assert np.array_equal(a, b)


def test_trace_equals_the_cli(dgauss, tmp_path):
    origins, directions = fan(21, 30.0)
    directions[:, 1] = 0.05
    rays = [{"origin": o.tolist(), "direction": d.tolist()} for o, d in zip(origins, directions)]
    path = tmp_path / "rays.json"
    path.write_text(json.dumps(rays))
    cli = cli_json("trace", "dgauss-50mm", "--rays", str(path), "--json")
    positions, headings, outcome, surface = dgauss.trace(origins, directions)
    names = {0: "ok", 1: "vignetted", 2: "tir", 3: "missed"}
    for k, row in enumerate(cli):
        assert row["status"] == names[int(outcome[k])]
        assert (row["surface"] or 0) == int(surface[k])
        if row["status"] == "ok":
            assert row["position"] == positions[k].tolist()
            assert row["direction"] == headings[k].tolist()


def test_trace_into_out_reuses_the_arrays(dgauss):
    origins, directions = fan(1500, 40.0)
    fresh = dgauss.trace(origins, directions)
    out = (np.full((1500, 3), 7.0), np.full((1500, 3), 7.0), np.full(1500, 9, np.uint8), np.full(1500, 9, np.uint32))
    returned = dgauss.trace(origins, directions, out=out)
    assert all(r is o for r, o in zip(returned, out))
    for a, b in zip(out, fresh):
        assert np.array_equal(a, b)


def test_trace_refuses_an_out_it_cannot_write_in_place(dgauss):
    origins, directions = fan(8, 1.0)
    good = lambda: [np.zeros((8, 3)), np.zeros((8, 3)), np.zeros(8, np.uint8), np.zeros(8, np.uint32)]
    short = good()
    short[0] = np.zeros((7, 3))
    with pytest.raises(lensbake.LensbakeError, match="positions out has 7 rows"):
        dgauss.trace(origins, directions, out=tuple(short))
    fortran = good()
    fortran[1] = np.zeros((8, 3), order="F")
    with pytest.raises(lensbake.LensbakeError, match=r"out\[1\] must be a C-ordered"):
        dgauss.trace(origins, directions, out=tuple(fortran))
    read_only = good()
    read_only[2].flags.writeable = False
    with pytest.raises(TypeError, match="not writeable"):
        dgauss.trace(origins, directions, out=tuple(read_only))
    wrong_dtype = good()
    wrong_dtype[3] = np.zeros(8, np.int64)
    with pytest.raises(TypeError):
        dgauss.trace(origins, directions, out=tuple(wrong_dtype))


def test_trace_paraxial_focus(dgauss):
    # A ray 0.01 mm off the axis crosses it at the paraxial rear focus.
    first = dgauss.analyze()["first_order"]
    positions, headings, outcome, _ = dgauss.trace([[0.0, 0.01, -10.0]], [[0.0, 0.0, 1.0]])
    assert outcome[0] == lensbake.OUTCOME_OK
    t = -positions[0, 1] / headings[0, 1]
    assert positions[0, 2] + t * headings[0, 2] == pytest.approx(first["z_rear_focal"], abs=1e-4)


def test_trace_refuses_bad_input_without_crashing(dgauss):
    origins, directions = fan(4, 1.0)
    with pytest.raises(lensbake.LensbakeError, match="n x 3"):
        dgauss.trace(origins[:, :2], directions[:, :2])
    with pytest.raises(lensbake.LensbakeError, match="directions has 3 rows where the positions have 4"):
        dgauss.trace(origins, directions[:3])
    bad = origins.copy()
    bad[2, 0] = np.nan
    with pytest.raises(lensbake.LensbakeError, match="ray 2"):
        dgauss.trace(bad, directions)
    zero = directions.copy()
    zero[1] = 0.0
    with pytest.raises(lensbake.LensbakeError, match="ray 1: .*zero length"):
        dgauss.trace(origins, zero)
    inside = origins.copy()
    inside[3, 2] = 5.0
    with pytest.raises(lensbake.LensbakeError, match="ray 3: .*must start"):
        dgauss.trace(inside, directions)
    with pytest.raises(lensbake.LensbakeError):
        dgauss.trace(origins, directions, wavelength_nm=1e9)
    # NumPy's own conversion refuses an array of the wrong dimension.
    with pytest.raises(TypeError, match="dimensionality"):
        dgauss.trace(np.zeros((2, 3, 1)), np.zeros((2, 3, 1)))


def test_trace_empty(dgauss):
    positions, headings, outcome, surface = dgauss.trace(np.zeros((0, 3)), np.zeros((0, 3)))
    assert positions.shape == (0, 3) and outcome.shape == (0,)


# -- wave optics -------------------------------------------------------------------------------


def test_wavefront_equals_the_cli(dgauss):
    python = dgauss.wavefront(field_deg=10.0, f_number=4.0)
    cli = cli_json("wavefront", "dgauss-50mm", "--field-deg", "10", "--f-number", "4", "--json")
    for key in ["rms_waves", "pv_waves", "strehl", "pupil_samples", "transmitted_samples"]:
        assert python[key] == cli[key], key
    assert python["reference_centre_mm"] == cli["reference_sphere"]["centre_mm"]
    assert python["reference_radius_mm"] == cli["reference_sphere"]["radius_mm"]
    opd, transmitted = python["opd_waves"], python["transmitted"]
    assert opd.shape == transmitted.shape == (64, 64)
    assert opd.dtype == np.float64 and transmitted.dtype == np.bool_
    assert int(transmitted.sum()) == python["transmitted_samples"]
    assert (opd[~transmitted] == 0.0).all()
    # RMS about the mean of the transmitted samples.
    values = opd[transmitted]
    assert math.sqrt(np.mean((values - values.mean()) ** 2)) == pytest.approx(python["rms_waves"], rel=1e-9)


def test_mtf_equals_the_cli(dgauss):
    python = dgauss.mtf(field_deg=5.0, wavelengths_nm=[486.13, 587.56, 656.27], weights=[1, 2, 1])
    cli = cli_json(
        "mtf", "dgauss-50mm", "--field-deg", "5", "--wavelength-nm", "486.13",
        "--wavelength-nm", "587.56", "--wavelength-nm", "656.27",
        "--weight", "1", "--weight", "2", "--weight", "1", "--json",
    )
    assert python["cutoff_per_mm"] == cli["cutoff_per_mm"]
    for key in ["frequencies_per_mm", "tangential", "sagittal", "diffraction_limit"]:
        assert python[key].dtype == np.float64
        assert python[key].tolist() == cli[key], key
    assert len(python["frequencies_per_mm"]) == 41


def test_mtf_at_chosen_frequencies(dgauss):
    curve = dgauss.mtf([0.0, 10.0, 50.0], f_number=8.0)
    assert curve["frequencies_per_mm"].tolist() == [0.0, 10.0, 50.0]
    assert curve["tangential"][0] == pytest.approx(1.0, abs=1e-12)
    # On the axis the lens is rotationally symmetric: tangential equals sagittal.
    assert np.allclose(curve["tangential"], curve["sagittal"], atol=1e-9)
    assert ((0.0 <= curve["tangential"]) & (curve["tangential"] <= 1.0 + 1e-12)).all()
    with pytest.raises(lensbake.LensbakeError, match="frequency"):
        dgauss.mtf([-1.0])
    with pytest.raises(lensbake.LensbakeError, match="not both"):
        dgauss.mtf(f_number=4.0, epd_mm=10.0)
    with pytest.raises(lensbake.LensbakeError, match="weight"):
        dgauss.mtf(wavelengths_nm=[500.0, 600.0], weights=[1.0])


def test_psf(dgauss):
    intensity, pixel_mm = dgauss.psf(f_number=8.0, grid=128, samples=32)
    assert intensity.shape == (128, 128) and intensity.dtype == np.float64
    assert 0.0 < intensity.max() <= 1.0 + 1e-9
    # The Strehl ratio is the PSF's peak over the aberration-free one.
    strehl = dgauss.wavefront(f_number=8.0, grid=128, samples=32)["strehl"]
    assert intensity.max() == pytest.approx(strehl, rel=2e-2)
    assert pixel_mm[0] > 0 and pixel_mm[1] > 0
    with pytest.raises(lensbake.LensbakeError, match="FFT grid"):
        dgauss.psf(samples=64, grid=64)
    with pytest.raises(lensbake.LensbakeError, match="field"):
        dgauss.psf(field_deg=95.0)


def test_wave_options_are_checked(dgauss):
    with pytest.raises(lensbake.LensbakeError, match="one wavelength"):
        dgauss.wavefront(wavelengths_nm=[500.0, 600.0])
    with pytest.raises(TypeError, match='unexpected keyword argument "feld_deg"'):
        dgauss.mtf(feld_deg=5.0)
    with pytest.raises(TypeError):
        dgauss.psf(samples="many")
    one = dgauss.wavefront(wavelengths_nm=[486.13], field_deg=3.0)
    assert one["wavelength_nm"] == 486.13 and one["field_deg"] == 3.0


# -- tables ------------------------------------------------------------------------------------


def film_rays(table, count):
    film_z = table.film_z()
    origins = np.zeros((count, 3))
    origins[:, 0] = np.linspace(0.0, 10.0, count)
    origins[:, 2] = film_z
    directions = np.tile([0.0, 0.0, -1.0], (count, 1))
    directions[:, 0] = -0.02
    return origins, directions


def test_table_lookup_matches_the_trace(dgauss, table):
    assert table.resolution == (16, 16, 16)
    assert table.wavelengths_nm == [dgauss.design_wavelength_nm]
    origins, directions = film_rays(table, 50)
    positions, headings, status = table.lookup(origins, directions)
    assert positions.shape == headings.shape == (50, 3) and status.dtype == np.uint8
    passes = status == lensbake.LOOKUP_PASSES
    assert passes.sum() > 25
    # The same rays traced backward through the lens: a 16³ table is within 0.1 mm, 2 mrad.
    traced, traced_dir, outcome, _ = dgauss.trace(origins, directions, backward=True)
    both = passes & (outcome == lensbake.OUTCOME_OK)
    assert both.sum() > 25
    assert np.abs(positions[both, :2] - traced[both, :2]).max() < 0.1
    assert np.abs(headings[both] - traced_dir[both]).max() < 2e-3
    assert (positions[~passes] == 0.0).all()


def test_table_lookup_focus_and_f_number(dgauss):
    ranged = lensbake.bake(dgauss, 12, focus_mm=5000.0, focus_near_mm=1000.0, f_number=2.8)
    assert ranged.f_number == pytest.approx(2.8)
    near, far = ranged.film_z(1000.0), ranged.film_z(5000.0)
    assert near > far
    origins, directions = film_rays(ranged, 8)
    origins[:, 2] = near
    _, _, status = ranged.lookup(origins, directions, focus_mm=1000.0, f_number=4.0)
    assert (status == lensbake.LOOKUP_PASSES).any()
    with pytest.raises(lensbake.LensbakeError, match="faster than the table"):
        ranged.lookup(origins, directions, f_number=2.0)
    with pytest.raises(lensbake.LensbakeError):
        ranged.lookup(origins, directions, focus_mm=100.0)
    with pytest.raises(lensbake.LensbakeError, match="layer"):
        ranged.lookup(origins, directions, layer=3)


def test_table_write_and_read(dgauss, table, tmp_path):
    table.write(tmp_path / "t")
    again = lensbake.read_table(tmp_path / "t", dgauss)
    origins, directions = film_rays(table, 20)
    for a, b in zip(table.lookup(origins, directions), again.lookup(origins, directions)):
        assert np.array_equal(a, b)
    with pytest.raises(lensbake.LensbakeError):
        lensbake.read_table(tmp_path / "t", lensbake.load_lens("cooke-triplet"))
    blind = lensbake.Table.read(tmp_path / "t")
    with pytest.raises(lensbake.LensbakeError, match="without its lens"):
        blind.write(tmp_path / "u")
    with pytest.raises(lensbake.LensbakeError):
        lensbake.read_table(tmp_path / "missing")


def test_bake_refuses_bad_requests(dgauss):
    with pytest.raises(lensbake.LensbakeError, match="at least 2 nodes"):
        lensbake.bake(dgauss, 1)
    with pytest.raises(lensbake.LensbakeError, match="precision"):
        lensbake.bake(dgauss, 8, precision="f8")
    with pytest.raises(lensbake.LensbakeError, match="faster"):
        lensbake.bake(dgauss, 8, f_number=0.7)
    with pytest.raises(lensbake.LensbakeError):
        table = lensbake.bake(dgauss, 8)
        table.lookup(np.full((1, 3), np.nan), np.ones((1, 3)))


# -- render and trade-off ----------------------------------------------------------------------


def test_render_traced_and_baked(dgauss, tmp_path):
    traced = lensbake.render(dgauss, width=32, height=24, samples_per_pixel=2)
    assert traced.shape == (24, 32, 3) and traced.dtype == np.float32
    assert np.isfinite(traced).all() and traced.max() > 0.0
    baked = lensbake.render(
        dgauss, model="baked", width=32, height=24, samples_per_pixel=2, table_dir=str(tmp_path / "t")
    )
    assert baked.shape == traced.shape
    # The same scene, lens and samples: the baked frame stays within 10 % of the traced one.
    assert np.abs(baked - traced).mean() < 0.1 * traced.mean()
    with pytest.raises(lensbake.LensbakeError):
        lensbake.render(dgauss, model="pinhole")
    with pytest.raises(lensbake.LensbakeError):
        lensbake.render(dgauss, width=0)


def test_tradeoff_meets_its_budget(dgauss):
    choice = lensbake.tradeoff(dgauss, 40.0, monochrome=True)
    assert choice["measured_px"] <= choice["budget_px"] == 40.0
    assert choice["model"] in {"thin", "thick", "seidel", "baked", "traced"}
    with pytest.raises(lensbake.LensbakeError):
        lensbake.tradeoff(dgauss, -1.0)


def test_help_says_units():
    doc = lensbake.Lens.trace.__doc__
    assert "mm" in doc and "n x 3" in doc and "uint8" in doc
