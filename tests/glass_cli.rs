//! `lensbake glass list` and `lensbake glass show` as a user runs them.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

#[test]
fn show_prints_the_standard_lines_abbe_number_formula_and_source() {
    let o = lensbake(&["glass", "show", "n-bk7"]);
    assert_eq!(o.status.code(), Some(0));
    let out = String::from_utf8_lossy(&o.stdout);
    // SCHOTT's datasheet: nF 1.522376, nd 1.516800, nC 1.514322 (6 decimals).
    for line in [
        "nF  (486.1327 nm)  1.522376",
        "nd  (587.5618 nm)  1.516800",
        "nC  (656.2725 nm)  1.514322",
    ] {
        assert!(out.contains(line), "{line} in\n{out}");
    }
    assert!(
        out.starts_with("N-BK7 (SCHOTT), glass code 517642\n"),
        "{out}"
    );
    assert!(
        out.contains("Vd 64.17") && out.contains("Sellmeier") && out.contains("SCHOTT.xls"),
        "{out}"
    );
}

#[test]
fn list_filters_by_catalogue_and_unknown_names_fail_with_suggestions() {
    let o = lensbake(&["glass", "list", "--catalog", "ohara"]);
    assert_eq!(o.status.code(), Some(0));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.lines().count() > 100, "{out}");
    assert!(out.lines().all(|l| l.contains(" OHARA ")), "{out}");
    assert!(out.contains("S-LAH64"), "{out}");
    // A withdrawn glass says so; a current one does not.
    let o = lensbake(&["glass", "list", "--catalog", "schott"]);
    let out = String::from_utf8_lossy(&o.stdout);
    let line = |name: &str| out.lines().find(|l| l.starts_with(name)).unwrap_or("");
    assert!(
        line("BK7_SCHOTT ").ends_with("withdrawn (1980 catalogue fit)"),
        "{out}"
    );
    assert!(line("N-BK7 ").ends_with("64.17"), "{out}");

    let o = lensbake(&["glass", "list", "--catalog", "NOPE"]);
    assert_eq!(o.status.code(), Some(2));
    let o = lensbake(&["glass", "show", "N-BK8"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.starts_with("error: unknown glass `N-BK8`; did you mean") && err.contains("N-BK7"),
        "{err}"
    );
}

/// An error that quotes what the user gave escapes its control characters: a terminal would act
/// on an escape sequence printed raw.
#[test]
fn errors_print_control_characters_escaped() {
    // A line break in the text would forge a second `error:` line.
    let output = lensbake(&["glass", "show", "N-BK7\u{1b}[31m\r\nerror: forged"]);
    assert_eq!(output.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.starts_with("error: ") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(!stderr.contains(['\u{1b}', '\r']), "{stderr:?}");
    assert!(
        stderr.contains("N-BK7\\u{1b}[31m\\r\\nerror: forged"),
        "{stderr:?}"
    );
}

/// The name's tolerance (case, dashes, a maker suffix) is for spelling: a name carrying a control
/// character is no glass, although its letters alone would spell one.
#[test]
fn a_name_with_control_characters_is_no_glass() {
    for name in ["N-BK7\u{7}", "N-\u{1b}BK7", "N-BK7\t"] {
        let output = lensbake(&["glass", "show", name]);
        assert_eq!(output.status.code(), Some(2), "{name:?}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.starts_with("error: unknown glass"), "{stderr}");
    }
}
