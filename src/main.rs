//! The `lensbake` command line. All printing happens here; the library returns data and errors.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // Held to the end of main: dropping it removes the directory.
    let _runtime_dir = give_drivers_a_runtime_dir();
    let args = cli::Cli::parse();
    let result = cli::run(args);
    // After the job: a closed stdout must not stop it from writing its files.
    let stdout_failure = cli::stdout::finish();
    let code = match (result, stdout_failure) {
        (Ok(()), None) => ExitCode::SUCCESS,
        (Ok(()), Some(error)) => {
            eprintln!("error: writing standard output: {error}");
            ExitCode::from(2)
        }
        (Err(error), _) => {
            eprintln!("error: {}", printable(&describe(&error)));
            ExitCode::from(2)
        }
    };
    // Notes still held follow the error line, or end a run that never released them.
    cli::notes::release();
    code
}

/// The error and its causes on one line, each said once: a library error that prints its cause
/// in its own message also returns it as its `source`, and the plain chain would repeat it.
fn describe(error: &anyhow::Error) -> String {
    let mut message = error.to_string();
    for cause in error.chain().skip(1) {
        let text = cause.to_string();
        if !message.contains(&text) {
            message.push_str(": ");
            message.push_str(&text);
        }
    }
    message
}

/// `text` with every control character escaped (`\u{1b}` for ESC, `\n` for a line break): an
/// error may quote a file's bytes, a terminal would act on its escape sequences, and a line
/// break would forge a second line (notes go through `cli::notes`, after the error line).
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// Graphics drivers (Mesa's among them) print `error: XDG_RUNTIME_DIR is invalid or not set` on
/// successful runs when the variable names no directory, which reads as a failure. A fresh
/// private directory (random name, mode 0700) stands in for it then; a fixed name under the
/// shared temporary directory could be made in advance, and owned, by another user.
fn give_drivers_a_runtime_dir() -> Option<tempfile::TempDir> {
    let valid =
        std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|dir| std::path::Path::new(&dir).is_dir());
    if valid {
        return None;
    }
    let dir = tempfile::Builder::new()
        .prefix("lensbake-runtime-")
        .tempdir()
        .ok()?;
    // SAFETY: called first thing in main, before any other thread exists that could read the
    // environment concurrently.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", dir.path()) };
    Some(dir)
}
