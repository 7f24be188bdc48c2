//! `note:` lines on stderr. A command's notes are held until it calls [`release`] (its inputs
//! read and checked, before long work) or ends. A command that fails first prints its `error:`
//! line before them, so an error is always the first line a script reads from stderr.

use std::cell::RefCell;

thread_local! {
    /// The notes held back; None once released, when notes print as they come.
    static HELD: RefCell<Option<Vec<String>>> = const { RefCell::new(Some(Vec::new())) };
}

pub fn note(text: String) {
    let not_held = HELD.with(|held| match held.borrow_mut().as_mut() {
        Some(list) => {
            list.push(text);
            None
        }
        None => Some(text),
    });
    if let Some(text) = not_held {
        eprintln!("note: {text}");
    }
}

/// Prints the held notes; later ones print as they come.
pub fn release() {
    let held = HELD
        .with(|held| held.borrow_mut().take())
        .unwrap_or_default();
    for text in held {
        eprintln!("note: {text}");
    }
}
