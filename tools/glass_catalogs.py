#!/usr/bin/env python3
"""Writes src/glass/data/<vendor>.tsv from the glass makers' own catalogue spreadsheets.

The spreadsheets are the ones the `opticalglass` package (PyPI, 1.1.1) redistributes in its
data/ folder; its catalogue classes know each sheet's layout (header rows, coefficient columns,
HOYA's mantissa/exponent pairs), so this script reads the sheets through them and writes one row
per glass:

    name  formula  coefficients(space separated)  nd  vd  min_nm  max_nm

formula is the vendor's published dispersion formula:
    sellmeier3   n^2 = 1 + sum B_i l^2 / (l^2 - C_i)                (SCHOTT, OHARA)
    sellmeier4   the same with four terms                           (CaF2 after Daimon, misc.tsv)
    schott6      n^2 = A0 + A1 l^2 + A2 l^-2 + A3 l^-4 + A4 l^-6 + A5 l^-8   (HOYA, CDGM, SUMITA)
    hikari9      n^2 = A0 + A1 l^2 + A2 l^4 + A3 l^-2 + ... + A8 l^-12      (HIKARI)
    buchdahl2    n = n0 + nu1 w + nu2 w^2, w = (l - 0.574) / (1 + 2.5 (l - 0.574))  (1980 glasses)
l in micrometres. nd and vd are the sheet's own (datasheet) values; min_nm..max_nm is the span of
wavelengths at which the sheet lists a measured index for that glass.

OHARA's spreadsheet keeps its low-softening-point moulding glasses (L-BAL35, L-LAH53, ...) on a
sheet of their own, "Low Tg glasses", which the opticalglass catalogue class does not read; they
are written to ohara-low-tg.tsv straight from that sheet (same columns, same formula).

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
    if formula.startswith("sellmeier"):
        terms = len(a) // 2
        n2 = 1 + sum(a[i] * l2 / (l2 - a[i + terms]) for i in range(terms))
    elif formula == "buchdahl2":
        w = buchdahl_omega(nm)
        return a[0] + a[1] * w + a[2] * w * w
    elif formula == "schott6":
        inv = 1 / l2
        n2 = a[0] + a[1] * l2 + sum(a[2 + k] * inv ** (k + 1) for k in range(4))
    else:
        inv = 1 / l2
        n2 = a[0] + a[1] * l2 + a[2] * l2 * l2 + sum(a[3 + k] * inv ** (k + 1) for k in range(6))
    return math.sqrt(n2)


def buchdahl_omega(nm):
    """Buchdahl's chromatic coordinate as Robb and Mercado use it: base 0.574 um, alpha 2.5."""
    shift = nm * 1e-3 - 0.574
    return shift / (1 + 2.5 * shift)


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


OHARA_LOW_TG_SHEET = "Low Tg glasses 5\u6841"
# Column numbers on that sheet (0-based): name, nd, vd, Sellmeier A1 A2 A3 B1 B2 B3 (OHARA's
# letters for B1 B2 B3 C1 C2 C3), and the first and last refractive-index columns.
LOW_TG_NAME, LOW_TG_ND, LOW_TG_VD, LOW_TG_COEFS = 1, 16, 24, range(60, 66)
LOW_TG_INDICES = range(4, 24)


def ohara_low_tg_rows():
    import pandas as pd
    import opticalglass

    path = os.path.join(os.path.dirname(opticalglass.__file__), "data", "OHARA.xlsx")
    sheet = pd.read_excel(path, sheet_name=OHARA_LOW_TG_SHEET, header=None)
    headers = sheet.iloc[1]
    rows = []
    for k in range(2, len(sheet)):
        row = sheet.iloc[k]
        name = str(row[LOW_TG_NAME]).replace(" ", "")
        if name == "nan":
            continue
        coefs = [float(f"{float(row[c]):.12g}") for c in LOW_TG_COEFS]
        nd, vd = float(row[LOW_TG_ND]), float(row[LOW_TG_VD])
        waves = []
        for c in LOW_TG_INDICES:
            label = str(headers[c]).strip()[1:]
            nm = float(label) if label.isdigit() else spectra.get(label)
            if nm is not None and not math.isnan(float(row[c])):
                waves.append(nm)
        nd_f = index("sellmeier3", coefs, D)
        vd_f = (nd_f - 1) / (index("sellmeier3", coefs, F) - index("sellmeier3", coefs, C))
        if abs(nd_f - nd) > 2e-5 or abs(vd_f - vd) > 0.05:
            print(f"ohara low Tg: {name}: formula nd {nd_f:.6f} vd {vd_f:.3f}, sheet {nd} {vd}",
                  file=sys.stderr)
        rows.append("\t".join([name, "sellmeier3", " ".join(repr(c) for c in coefs), repr(nd),
                               repr(vd), repr(min(waves)), repr(max(waves))]))
    return rows


def write_tsv(file_name, source, columns, rows):
    """One data file: the source line, the column header, one row per glass."""
    with open(os.path.join(OUT, file_name), "w", encoding="utf-8") as out:
        out.write(f"# {source}\n# {columns}\n")
        out.write("\n".join(rows) + "\n")


def write_ohara_low_tg():
    write_tsv("ohara-low-tg.tsv",
              "OHARA low-Tg moulding glasses from the sheet \"Low Tg glasses\" of the maker's "
              "spreadsheet OHARA.xlsx (opticalglass 1.1.1 data/)",
              "name\tformula\tcoefficients\tnd\tvd\tmin_nm\tmax_nm", ohara_low_tg_rows())


# Crystals and special glasses that no vendor sheet above holds, from the refractiveindex.info
# database (CC0) as shipped inside optiland 0.6.3 (optiland/database/data-nk/...).
MISC = [
    ("SILICA", "main/SiO2/Malitson.yml", "fused silica, Malitson, JOSA 55, 1205 (1965)"),
    ("CAF2", "main/CaF2/Malitson.yml", "calcium fluoride, Malitson, Appl. Opt. 2, 1103 (1963)"),
    # Named as lens files name it (optiland's CODE V sample telescope_objective.seq): the
    # database's page CaF2 "Daimon-20", measured at 20 degrees C.
    ("CAF2_DAIMON-20", "main/CaF2/Daimon-20.yml",
     "calcium fluoride at 20 C, Daimon and Masumura, Appl. Opt. 41, 5275 (2002)"),
    ("SAPPHIRE", "main/Al2O3/Malitson-o.yml",
     "sapphire ordinary ray, Malitson and Dodge, JOSA 62, 1405 (1972)"),
    ("B270", "glass/schott/misc/B270.yml", "SCHOTT B 270 datasheet, August 1993 (tabulated)"),
    # Infrared crystals under the names Zemax's infrared catalogue gives them.
    ("ZNSE", "main/ZnSe/Connolly.yml",
     "zinc selenide (CVD, 23 C), Tatian, Appl. Opt. 23, 4477 (1984), fitted to the data of "
     "Connolly et al., Proc. SPIE 181, 141 (1979)"),
    ("MGF2", "main/MgF2/Dodge-o.yml",
     "magnesium fluoride ordinary ray (19 C), Dodge, Appl. Opt. 23, 1980 (1984)"),
    ("BAF2", "main/BaF2/Malitson.yml", "barium fluoride (25 C), Malitson, JOSA 54, 628 (1964)"),
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
        elif data["type"].strip() == "formula 2":
            c = [float(x) for x in data["coefficients"].split()]
            # formula 2: n^2 - 1 = c0 + sum B l^2 / (l^2 - C), C in square micrometres
            assert c[0] == 0.0, rel
            terms = (len(c) - 1) // 2
            coefs = c[1::2] + c[2::2]
            formula = f"sellmeier{terms}"
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
    write_tsv("misc.tsv",
              "Crystals and special glasses from the refractiveindex.info database (CC0); "
              "nd and vd computed from the data",
              "name\tformula\tcoefficients\tnd\tvd\tmin_nm\tmax_nm\tsource", misc_rows())


# Glasses of the 1980 SCHOTT, OHARA and HOYA catalogues as Robb and Mercado fitted them:
# Buchdahl's quadratic model n = n0 + nu1 w + nu2 w^2 over the visible (Appl. Opt. 22, 1198
# (1983), Table V), as transcribed in opticalglass 1.1.1 data/robb1983_data_final.txt.
ROBB_1980 = {"SCHOTT": "schott-1980.tsv", "OHARA": "ohara-1980.tsv", "HOYA": "hoya-1980.tsv"}
# The sheets each 1980 catalogue stands behind: a name they hold is read from them.
CURRENT = {"SCHOTT": ["schott.tsv", "schott-legacy.tsv"], "OHARA": ["ohara.tsv", "ohara-low-tg.tsv"],
           "HOYA": ["hoya.tsv"]}
# Corroborated when another 1980 catalogue's glass of the same name has nd within this and vd
# within VD_AGREE: makers matched their rivals' glasses that closely, and the two rows were
# transcribed apart, so an agreeing pair is read right. Rows nobody corroborates are left out:
# some of the transcription pairs a name with another glass's numbers (SCHOTT SF56 and SF57 give
# nd 1.728 and 1.761; the glasses are 1.785 and 1.847).
ND_AGREE, VD_AGREE = 2e-3, 1.0


def glass_key(name):
    return "".join(ch for ch in name.upper() if ch.isalnum())


def robb_1980_tables():
    import opticalglass

    path = os.path.join(os.path.dirname(opticalglass.__file__), "data", "robb1983_data_final.txt")
    tables, maker = {}, None
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("#"):
                if "GLASS CATALOGUE" in line:
                    maker = line[1:].split()[0]
                continue
            name, n0, nu1, nu2 = line.split()[:4]
            coefs = [float(n0), float(nu1), float(nu2)]
            nd = index("buchdahl2", coefs, D)
            vd = (nd - 1) / (index("buchdahl2", coefs, F) - index("buchdahl2", coefs, C))
            tables.setdefault(maker, {})[glass_key(name)] = (name, coefs, nd, vd)
    return tables


def held_names(files):
    names = set()
    for file_name in files:
        with open(os.path.join(OUT, file_name), encoding="utf-8") as f:
            names |= {glass_key(l.split("\t")[0]) for l in f if not l.startswith("#")}
    return names


def write_robb_1980():
    tables = robb_1980_tables()
    for maker, file_name in ROBB_1980.items():
        held = held_names(CURRENT[maker])
        rows, alone, disputed = [], 0, []
        for key, (name, coefs, nd, vd) in tables[maker].items():
            if key in held:
                continue
            others = [t[key] for m, t in tables.items() if m != maker and key in t]
            if not others:
                alone += 1
                continue
            if not all(abs(nd - o[2]) < ND_AGREE and abs(vd - o[3]) < VD_AGREE for o in others):
                disputed.append(name)
                continue
            rows.append("\t".join([name, "buchdahl2", " ".join(repr(c) for c in coefs),
                                   f"{nd:.6f}", f"{vd:.2f}", "400", "700"]))
        print(f"{maker} 1980: {len(rows)} written, {alone} uncorroborated, disputed {disputed}",
              file=sys.stderr)
        write_tsv(file_name,
                  f"{maker} 1980 catalogue glasses that later sheets dropped, as Buchdahl quadratic "
                  "fits over 400-700 nm by Robb and Mercado, Appl. Opt. 22, 1198 (1983), Table V "
                  "(transcription in opticalglass 1.1.1 data/robb1983_data_final.txt); nd and vd "
                  "computed from the fit",
                  "name\tformula\tcoefficients (n0 nu1 nu2)\tnd\tvd\tmin_nm\tmax_nm", rows)


if __name__ == "__main__":
    main()
    write_ohara_low_tg()
    write_misc()
    write_robb_1980()
