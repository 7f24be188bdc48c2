//! The one writer of standard output. A closed stdout (a reader such as `head` that stopped, or
//! `> /dev/full`) is not a failure of the job: the text is dropped and the run goes on to write
//! its files. A write error other than a closed pipe is reported once, at the end ([`finish`]).

use std::fmt;
use std::io::{ErrorKind, Write};
use std::sync::Mutex;

static FAILURE: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Writes formatted text to stdout; see [`say!`](crate::say) and [`say_raw!`](crate::say_raw).
pub fn write(text: fmt::Arguments, newline: bool) {
    let mut out = std::io::stdout().lock();
    let written = out.write_fmt(text).and_then(|()| {
        if newline {
            out.write_all(b"\n")
        } else {
            Ok(())
        }
    });
    if let Err(error) = written {
        record(error);
    }
}

fn record(error: std::io::Error) {
    if error.kind() == ErrorKind::BrokenPipe {
        return;
    }
    let mut failure = FAILURE
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    failure.get_or_insert(error);
}

/// Flushes stdout; the first write error that was not a closed pipe, if any.
pub fn finish() -> Option<std::io::Error> {
    if let Err(error) = std::io::stdout().lock().flush() {
        record(error);
    }
    FAILURE
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
        .take()
}
