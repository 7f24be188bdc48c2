"""Wavefront RMS and FFT MTF from optiland 0.6.3 for the truth-data lenses, as test data.

Writes tests/data/wave/optiland_wave.json, which tests/wave_peer.rs compares lensbake against;
both sides build each lens from the same truth-data table (tests/data/truth/oracle, constant
indices at one wavelength).

    python benches/peer/peer_wave.py        (with optiland==0.6.3 installed)

Sampling, the same on both sides (docs/wave.md):
- OPD: optiland's `OPD` with the chief-ray reference sphere, tilt kept, on the "uniform"
  distribution of 64 x 64 points masked to the unit pupil; the RMS is taken about the mean
  (piston removed), which optiland's own `rms()` does not do (it is stored too, for reference).
- MTF: optiland's `FFTMTF` with num_rays=128, which samples the pupil with 64 points per side
  on a 256 grid, stored at its own frequency samples (whole pupil lags, near the stated
  fractions of the cutoff), so that no interpolation enters the comparison.
The image plane is the paraxial focus (`image_solve`), the primary wavelength the table's.
"""

import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peer_trace import oracle_dir, optiland_lens  # noqa: E402

from optiland.mtf import FFTMTF  # noqa: E402
from optiland.wavefront import OPD  # noqa: E402

LENSES = ["pbrt_dgauss_50mm", "kolb_dgauss_1995_nobj1", "codev_ag_dblgauss", "optiland_cooke_triplet"]
FIELD_FRACTIONS = [0.0, 0.5, 0.7, 1.0]
CUTOFF_FRACTIONS = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]
OPD_SAMPLES = 64
MTF_NUM_RAYS = 128


def out_dir():
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "tests", "data", "wave"))


def lens_record(name):
    with open(os.path.join(oracle_dir(), name + ".json")) as f:
        lens = json.load(f)["lenses"][0]
    optic = optiland_lens(lens)
    max_field = lens["system"]["max_field_angle_deg"]
    optic.fields.add(y=max_field)
    optic.image_solve()
    wavelength_nm = 1000.0 * optic.primary_wavelength
    fno = optic.paraxial.FNO()
    fields = []
    for fraction in FIELD_FRACTIONS:
        field = (0.0, fraction)
        opd = OPD(optic, field, "primary", num_rays=OPD_SAMPLES, distribution="uniform")
        data = opd.get_data(opd.fields[0], opd.wavelengths[0])
        mask = np.asarray(data.intensity) > 0
        w = np.asarray(data.opd)[mask]
        mtf = FFTMTF(optic, fields=[field], wavelength="primary", num_rays=MTF_NUM_RAYS)
        lags = [round(c * (mtf.num_rays - 1)) for c in CUTOFF_FRACTIONS]
        axes = {}
        for key, freq, values in [("tangential", mtf.freq_tang[0], mtf.mtf[0][0]),
                                  ("sagittal", mtf.freq_sag[0], mtf.mtf[0][1])]:
            axes[key] = {
                "frequencies_per_mm": [float(np.asarray(freq)[k]) for k in lags],
                "mtf": [float(np.asarray(values)[k]) for k in lags],
            }
        fields.append({
            "field_deg": fraction * max_field,
            "rms_waves_piston_removed": float(np.sqrt(np.mean((w - w.mean()) ** 2))),
            "rms_waves_optiland": float(opd.rms()),
            "pv_waves": float(w.max() - w.min()),
            "transmitted_samples": int(mask.sum()),
            "mtf": axes,
        })
    return {
        "lens": name,
        "oracle": name + ".json",
        "epd_mm": lens["system"]["epd_used"],
        "wavelength_nm": wavelength_nm,
        "f_number": float(fno),
        "fields": fields,
    }


def main():
    os.makedirs(out_dir(), exist_ok=True)
    records = []
    for name in LENSES:
        record = lens_record(name)
        records.append(record)
        print(name, [round(f["rms_waves_piston_removed"], 4) for f in record["fields"]], file=sys.stderr)
    payload = {
        "generator": "benches/peer/peer_wave.py",
        "optiland": "0.6.3",
        "opd_samples": OPD_SAMPLES,
        "mtf_num_rays": MTF_NUM_RAYS,
        "lenses": records,
    }
    with open(os.path.join(out_dir(), "optiland_wave.json"), "w") as f:
        json.dump(payload, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
