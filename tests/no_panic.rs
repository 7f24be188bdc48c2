//! Random bytes and randomly mutated lens files go through every reader (and, when they parse,
//! through validation, glass resolution, the per-wavelength view and the RON writer): each must
//! return Ok or a located error, never panic. Seeded, so a failure reproduces.

mod common;

use common::{Rng, lens_file, test_data};
use lensbake::prescription::formats::{
    Format, LoadOptions, PbrtThickness, read_bytes, read_str, write_ron,
};
use lensbake::system::LensSystem;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

/// Tokens that reach the corners of the readers.
const TOKENS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "1e308",
    "-1e308",
    "1e-320",
    "inf",
    "-inf",
    "NaN",
    "N/A",
    "STO",
    "stop",
    "#",
    "!",
    ";",
    "'",
    "\"",
    "(",
    ")",
    "[",
    "]",
    ",",
    ":",
    "S",
    "SO",
    "SI",
    "CIR",
    "EPD 0",
    "RDM N",
    "DIM I",
    "K -1",
    "A 1e30",
    "YAN 89.9",
    "VUY 2",
    "REF 99",
    "FNO 0",
    "SURF 1",
    "SURF 0",
    "TYPE EVENASPH",
    "PARM 9 1",
    "DISZ INFINITY",
    "GLAS ___BLANK 1 0 0 0",
    "STOP",
    "FLOA",
    "WAVM 99999999999 0.5",
    "PWAV 0",
    "UNIT M",
    "Some(",
    "None",
    "Glass(\"N-BK7\")",
    "Blades(count: 0)",
    "EvenAsphere(",
    "\u{feff}",
    "é",
    "\t",
    "\r\n",
    "\n",
    "99999999999999999999.1",
    "0.000000001",
    "622292.5788",
    "123456",
];

fn mutate(rng: &mut Rng, input: &[u8]) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(out.len() + 1);
        match rng.below(6) {
            0 if !out.is_empty() => {
                let i = rng.below(out.len());
                out[i] = rng.next() as u8;
            }
            1 if !out.is_empty() => {
                let end = (at + 1 + rng.below(40)).min(out.len());
                out.drain(at.min(end)..end);
            }
            2 => {
                let token = TOKENS[rng.below(TOKENS.len())];
                let spaced = if rng.below(2) == 0 {
                    format!(" {token} ")
                } else {
                    token.to_string()
                };
                out.splice(at..at, spaced.into_bytes());
            }
            3 if !out.is_empty() => {
                // Duplicate a stretch (whole rows, commands or RON entries, with luck).
                let start = rng.below(out.len());
                let end = (start + 1 + rng.below(80)).min(out.len());
                let copy = out[start..end].to_vec();
                out.splice(at..at, copy);
            }
            4 => {
                // Swap two lines.
                let text = String::from_utf8_lossy(&out).into_owned();
                let mut lines: Vec<&str> = text.split('\n').collect();
                let (a, b) = (rng.below(lines.len()), rng.below(lines.len()));
                lines.swap(a, b);
                out = lines.join("\n").into_bytes();
            }
            _ => {
                let digit = b"0123456789.-e"[rng.below(13)];
                out.insert(at, digit);
            }
        }
    }
    out
}

/// Reads `bytes` as every format under both pbrt conventions and at zoom position 2, writes and
/// rereads what loads, and validates it; returns how many of those reads loaded and how many
/// became a lens system.
fn exercise(bytes: &[u8]) -> (usize, usize) {
    let (mut loaded_count, mut valid_count) = (0, 0);
    let file = Some(Path::new("fuzz.lens"));
    for format in Format::ALL {
        for (pbrt_thickness, zoom_position) in [
            (PbrtThickness::ToNext, None),
            (PbrtThickness::FromPrevious, None),
            (PbrtThickness::ToNext, Some(2)),
        ] {
            let options = LoadOptions {
                pbrt_thickness,
                zoom_position,
                ..LoadOptions::default()
            };
            let Ok(loaded) = read_bytes(bytes, file, format, &options) else {
                continue;
            };
            loaded_count += 1;
            let _ = loaded.notes.iter().map(ToString::to_string).count();
            let text = write_ron(&loaded.prescription);
            let again = read_str(&text, None, Format::Ron, &LoadOptions::default());
            assert!(again.is_ok(), "written RON does not read back: {text}");
            if let Ok(system) = LensSystem::new(loaded.prescription, &loaded.map) {
                let at = system.at(system.design_wavelength_nm());
                assert_eq!(at.surfaces.len(), system.prescription.surfaces.len());
                valid_count += 1;
            }
        }
    }
    (loaded_count, valid_count)
}

fn seeds() -> Vec<Vec<u8>> {
    let mut seeds: Vec<Vec<u8>> = std::fs::read_dir(lens_file(""))
        .expect("lens directory")
        .map(|e| std::fs::read(e.expect("entry").path()).expect("lens file"))
        .collect();
    seeds.push(std::fs::read(test_data("cooke_triplet.zmx")).expect("fixture"));
    seeds.push(std::fs::read(test_data("zoom_two_group.seq")).expect("fixture"));
    // The RON form of a lens, so the RON reader gets near-valid input too.
    let table = std::fs::read_to_string(lens_file("dgauss.50mm.dat")).expect("lens file");
    let loaded = read_str(&table, None, Format::Pbrt, &LoadOptions::default()).expect("pbrt file");
    seeds.push(write_ron(&loaded.prescription).into_bytes());
    seeds
}

#[test]
fn readers_never_panic() {
    let mut rng = Rng(0x5EED_1E45_BA4E_0001);
    let seeds = seeds();
    // Inputs some reader loaded, and inputs that became a valid lens, among the mutated ones.
    let (mut loaded, mut valid) = (0, 0);
    let mut run = |bytes: Vec<u8>| match catch_unwind(AssertUnwindSafe(|| exercise(&bytes))) {
        Ok((l, v)) => {
            loaded += usize::from(l > 0);
            valid += usize::from(v > 0);
        }
        Err(_) => panic!(
            "panicked on input:\n{}",
            String::from_utf8_lossy(&bytes).escape_debug()
        ),
    };
    for _ in 0..300 {
        let len = rng.below(300);
        run((0..len).map(|_| rng.next() as u8).collect());
    }
    for round in 0..6000 {
        let seed = &seeds[round % seeds.len()];
        let mut bytes = mutate(&mut rng, seed);
        if rng.below(4) == 0 {
            bytes = mutate(&mut rng, &bytes);
        }
        run(bytes);
    }
    eprintln!("6300 fuzz inputs: {loaded} loaded by some reader, {valid} valid lenses");
    // The mutations must reach past the readers' first checks into validation, and must break
    // many inputs: a fuzz whose inputs all fail to parse (or all parse) tests one path only.
    assert!(
        loaded >= 1000 && valid >= 500,
        "{loaded} loaded, {valid} valid"
    );
    assert!(
        6300 - valid >= 1000,
        "only {} of 6300 inputs rejected",
        6300 - valid
    );
}
