//! Issue 58, defect 8: `render`, `tradeoff` and `report` show their progress on a terminal
//! (an indicatif spinner on stderr, as `bake` shows a bar) and print nothing of it when stderr
//! is not a terminal, so that scripts and tests read the same output as before. The terminal
//! is a pseudo-terminal from util-linux's `script`.
#![cfg(feature = "cli")]

mod common;

use std::process::Command;

/// `lensbake ARGS` with stdout and stderr on a pseudo-terminal; what it showed there (None where
/// `script` is missing).
fn on_a_terminal(args: &[&str]) -> Option<String> {
    let mut line = String::from(env!("CARGO_BIN_EXE_lensbake"));
    for arg in args {
        line.push(' ');
        line.push_str(arg);
    }
    let out = Command::new("script")
        .args(["-qec", &line, "/dev/null"])
        .output()
        .ok()?;
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

#[test]
fn long_commands_show_progress_on_a_terminal_and_nothing_elsewhere() {
    let dir = std::env::temp_dir().join(format!("lensbake-progress-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let image = dir.join("r.exr");
    let report = dir.join("report");
    let image = image.to_str().unwrap();
    let report = report.to_str().unwrap();
    let render = [
        "render",
        "--lens",
        "dgauss-50mm",
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "4",
        "--backend",
        "cpu",
        "--out",
        image,
    ];
    let report_args = ["report", "cooke-triplet", "--out", report];
    for (args, shown) in [
        (&render[..], "rendering "),
        (&report_args[..], "writing the report"),
    ] {
        let plain = common::lensbake(args);
        let stderr = String::from_utf8_lossy(&plain.stderr);
        assert!(plain.status.success(), "{stderr}");
        assert!(!stderr.contains(shown), "not a terminal: {stderr}");
        match on_a_terminal(args) {
            Some(terminal) => assert!(
                terminal.contains(shown),
                "{args:?} showed no progress on a terminal:\n{terminal}"
            ),
            None => {
                assert!(
                    std::env::var("CI").as_deref() != Ok("true"),
                    "script (util-linux) is missing"
                );
                eprintln!("SKIPPED the terminal half: no `script` (util-linux)");
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
