#!/usr/bin/env python3
"""Writes src/glass/data/<vendor>.tsv from the glass makers' own catalogue spreadsheets.

The spreadsheets are the ones the `opticalglass` package (PyPI, 1.1.1) redistributes in its
data/ folder; its catalogue classes know each sheet's layout (header rows, coefficient columns,
HOYA's mantissa/exponent pairs), so this script reads the sheets through them and writes one row
per glass:

    name  formula  coefficients(space separated)  nd  vd  min_nm  max_nm

formula is the vendor's published dispersion formula:
    sellmeier3   n^2 = 1 + sum B_i l^2 / (l^2 - C_i)                (SCHOTT, OHARA)
    schott6      n^2 = A0 + A1 l^2 + A2 l^-2 + A3 l^-4 + A4 l^-6 + A5 l^-8   (HOYA, CDGM, SUMITA)
    hikari9      n^2 = A0 + A1 l^2 + A2 l^4 + A3 l^-2 + ... + A8 l^-12      (HIKARI)
l in micrometres. nd and vd are the sheet's own (datasheet) values; min_nm..max_nm is the span of
wavelengths at which the sheet lists a measured index for that glass.

Run:  python3 -m venv /tmp/venv && /tmp/venv/bin/pip install opticalglass==1.1.1 openpyxl xlrd
      /tmp/venv/bin/python tools/glass_catalogs.py
It also prints, per vendor, the largest |n_formula(d) - nd| and |vd_formula - vd| found.
"""
import math
import os
import sys
import warnings

warnings.filterwarnings("ignore")
from opticalglass import cdgm, hikari, hoya, ohara, schott, sumita  # noqa: E402
from opticalglass.spectral_lines import spectra  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "src", "glass", "data")
D, F, C = 587.5618, 486.1327, 656.2725

VENDORS = [
    ("schott", schott.SchottCatalog, "SCHOTT.xls", "sellmeier3"),
    ("ohara", ohara.OharaCatalog, "OHARA.xlsx", "sellmeier3"),
    ("hoya", hoya.HoyaCatalog, "HOYA.xlsx", "schott6"),
    ("cdgm", cdgm.CDGMCatalog, "CDGM.xls", "schott6"),
    ("hikari", hikari.HikariCatalog, "HIKARI.xlsx", "hikari9"),
    ("sumita", sumita.SumitaCatalog, "SUMITA.xlsx", "schott6"),
]


def index(formula, a, nm):
    l2 = (nm * 1e-3) ** 2
    if formula == "sellmeier3":
        n2 = 1 + sum(a[i] * l2 / (l2 - a[i + 3]) for i in range(3))
    elif formula == "schott6":
        inv = 1 / l2
        n2 = a[0] + a[1] * l2 + sum(a[2 + k] * inv ** (k + 1) for k in range(4))
    else:
        inv = 1 / l2
        n2 = a[0] + a[1] * l2 + a[2] * l2 * l2 + sum(a[3 + k] * inv ** (k + 1) for k in range(6))
    return math.sqrt(n2)


def wavelength_nm(header):
    if isinstance(header, (int, float)) and not isinstance(header, bool):
        return float(header)
    return spectra.get(str(header).strip())


def coefficients(catalog, sheet_name):
    """The sheet's dispersion coefficients; HIKARI writes an absent term as '-'."""
    try:
        raw = catalog.glass_coefs(sheet_name)
    except ValueError:
        raw = catalog.df.loc[sheet_name]["dispersion coefficients"]
    return [0.0 if str(c).strip() == "-" else float(f"{float(c):.12g}") for c in raw]


def first(row, keys):
    for key in keys:
        try:
            value = float(row[key])
        except (KeyError, TypeError, ValueError):
            continue
        if not math.isnan(value):
            return value
    return None


def measured_span(row):
    waves = []
    for (group, header), value in row.items():
        if group != "refractive indices":
            continue
        nm = wavelength_nm(header)
        try:
            ok = nm is not None and not math.isnan(float(value))
        except (TypeError, ValueError):
            ok = False
        if ok:
            waves.append(nm)
    return (min(waves), max(waves)) if waves else (None, None)


def main():
    for vendor, catalog_class, sheet, formula in VENDORS:
        catalog = catalog_class()
        rows, worst_nd, worst_vd = [], 0.0, 0.0
        for sheet_name in sorted(str(n) for n in catalog.get_glass_names()):
            if not sheet_name or sheet_name == "nan":
                continue
            row = catalog.df.loc[sheet_name]
            # OHARA's sheet writes "S-LAL 7"; the maker's Zemax catalogue and lens files "S-LAL7".
            name = sheet_name.replace(" ", "")
            # CDGM marks a variant of a glass with "*" (H-K9L*); lens files cannot tell the two
            # apart by name, so the plain glass is kept and the variant left out.
            if name.endswith("*") and name[:-1] in catalog.get_glass_names():
                print(f"{vendor}: {name} left out (same name as {name[:-1]})", file=sys.stderr)
                continue
            coefs = coefficients(catalog, sheet_name)
            nd = first(row, [("refractive indices", "d"), ("refractive index", "d")])
            vd = first(row, [("abbe number", "vd")])
            if nd is None or vd is None or any(math.isnan(c) for c in coefs):
                print(f"{vendor}: {name} lacks nd, vd or coefficients; left out", file=sys.stderr)
                continue
            lo, hi = measured_span(row)
            nd_f = index(formula, coefs, D)
            vd_f = (nd_f - 1) / (index(formula, coefs, F) - index(formula, coefs, C))
            worst_nd = max(worst_nd, abs(nd_f - nd))
            worst_vd = max(worst_vd, abs(vd_f - vd))
            if abs(nd_f - nd) > 2e-5 or abs(vd_f - vd) > 0.05:
                print(f"{vendor}: {name}: formula nd {nd_f:.6f} vd {vd_f:.3f}, sheet {nd} {vd}",
                      file=sys.stderr)
            rows.append(
                "\t".join(
                    [name, formula, " ".join(repr(c) for c in coefs), repr(nd), repr(vd),
                     repr(lo), repr(hi)]
                )
            )
        path = os.path.join(OUT, f"{vendor}.tsv")
        with open(path, "w", encoding="utf-8") as out:
            out.write(f"# {vendor.upper()} catalogue from the maker's spreadsheet {sheet} "
                      "(opticalglass 1.1.1 data/)\n")
            out.write("# name\tformula\tcoefficients\tnd\tvd\tmin_nm\tmax_nm\n")
            out.write("\n".join(rows) + "\n")
        print(f"{vendor}: {len(rows)} glasses; max |n(d)-nd| {worst_nd:.2e}, "
              f"max |vd-vd_sheet| {worst_vd:.3f}")


# Crystals and special glasses that no vendor sheet above holds, from the refractiveindex.info
# database (CC0) as shipped inside optiland 0.6.3 (optiland/database/data-nk/...).
MISC = [
    ("SILICA", "main/SiO2/Malitson.yml", "fused silica, Malitson, JOSA 55, 1205 (1965)"),
    ("CAF2", "main/CaF2/Malitson.yml", "calcium fluoride, Malitson, Appl. Opt. 2, 1103 (1963)"),
    ("SAPPHIRE", "main/Al2O3/Malitson-o.yml",
     "sapphire ordinary ray, Malitson and Dodge, JOSA 62, 1405 (1972)"),
    ("B270", "glass/schott/misc/B270.yml", "SCHOTT B 270 datasheet, August 1993 (tabulated)"),
]


def misc_rows():
    import optiland
    import yaml

    base = os.path.join(os.path.dirname(optiland.__file__), "database", "data-nk")
    rows = []
    for name, rel, source in MISC:
        with open(os.path.join(base, rel), encoding="utf-8") as f:
            data = yaml.safe_load(f)["DATA"][0]
        if data["type"] == "formula 1":
            c = [float(x) for x in data["coefficients"].split()]
            # formula 1: n^2 - 1 = c0 + sum B l^2 / (l^2 - C^2), C in micrometres
            assert c[0] == 0.0, rel
            coefs = [c[1], c[3], c[5], c[2] ** 2, c[4] ** 2, c[6] ** 2]
            formula = "sellmeier3"
            lo, hi = (float(x) * 1e3 for x in data["wavelength_range"].split())
        else:
            pairs = [line.split() for line in data["data"].strip().splitlines()]
            # The datasheet lists indices at spectral lines; the database rounds their
            # wavelengths to 10 pm, so snap each back to its line.
            lines = [v for v in spectra.values() if isinstance(v, float)]
            snap = [min(lines, key=lambda l: abs(l - float(um) * 1e3)) for um, _ in pairs]
            coefs = [v for (um, n), line in zip(pairs, snap)
                     for v in (line if abs(line - float(um) * 1e3) < 0.01 else float(um) * 1e3,
                               float(n))]
            formula = "tabulated"
            lo, hi = coefs[0], coefs[-2]
        nd = index_any(formula, coefs, D)
        vd = (nd - 1) / (index_any(formula, coefs, F) - index_any(formula, coefs, C))
        rows.append("\t".join([name, formula, " ".join(f"{x:.12g}" for x in coefs),
                               f"{nd:.6f}", f"{vd:.2f}", repr(lo), repr(hi), source]))
    return rows


def index_any(formula, coefs, nm):
    if formula != "tabulated":
        return index(formula, coefs, nm)
    points = list(zip(coefs[::2], coefs[1::2]))
    for (l0, n0), (l1, n1) in zip(points, points[1:]):
        if l0 <= nm <= l1:
            return n0 + (n1 - n0) * (nm - l0) / (l1 - l0)
    raise ValueError(nm)


def write_misc():
    path = os.path.join(OUT, "misc.tsv")
    with open(path, "w", encoding="utf-8") as out:
        out.write("# Crystals and special glasses from the refractiveindex.info database (CC0); "
                  "nd and vd computed from the data\n")
        out.write("# name\tformula\tcoefficients\tnd\tvd\tmin_nm\tmax_nm\tsource\n")
        out.write("\n".join(misc_rows()) + "\n")


if __name__ == "__main__":
    main()
    write_misc()
