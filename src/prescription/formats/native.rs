//! lensbake's own format: the [`Prescription`] serialised as RON. Canonical (one layout for one
//! prescription) and exact: floats are written as the shortest text that parses back to the
//! same bits.

use super::{Format, Loaded, Source};
use crate::prescription::error::{PrescriptionError, Problem};
use crate::prescription::model::Prescription;
use crate::prescription::validate::SourceMap;

pub(super) fn read(text: &str, source: &Source) -> Result<Loaded, PrescriptionError> {
    if text.trim().is_empty() {
        return Err(source.error(None, Problem::Empty));
    }
    let layout = SurfaceLayout::scan(text);
    // Counted before RON builds the list: a file of millions of surfaces would otherwise be
    // parsed whole only to be refused by validation.
    crate::limits::check(
        "the number of surfaces",
        layout.starts.len() as u64,
        crate::limits::MAX_SURFACES,
    )
    .map_err(|e| {
        let first_over = layout.starts.get(crate::limits::MAX_SURFACES as usize);
        source.error(first_over.copied(), e.into())
    })?;
    let prescription: Prescription = ron::Options::default().from_str(text).map_err(|e| {
        let line = e.span.start.line;
        let mut location = source.location(Some(line));
        location.surface = layout.surface_at(line).map(|i| i + 1);
        PrescriptionError::new(
            location,
            Problem::Syntax(format!("{} (column {})", e.code, e.span.start.col)),
        )
    })?;
    let map = SourceMap {
        file: None,
        surface_lines: layout.starts.iter().map(|&l| Some(l)).collect(),
        ..SourceMap::default()
    };
    Ok(Loaded {
        prescription,
        map,
        format: Format::Ron,
        notes: Vec::new(),
    })
}

pub(super) fn write(p: &Prescription) -> String {
    let config = ron::ser::PrettyConfig::new()
        .indentor("    ".to_string())
        .struct_names(false);
    let mut text = ron::ser::to_string_pretty(p, config)
        .expect("a Prescription holds only strings, numbers, options, enums and lists, which RON always encodes");
    text.push('\n');
    text
}

/// Where each surface's entry starts in the text, found by a light scan that knows RON's
/// brackets, strings and comments, so that errors (from RON or from validation) cite lines.
#[derive(Debug, Default)]
struct SurfaceLayout {
    /// 1-based line where each surface entry starts.
    starts: Vec<usize>,
    /// 1-based line of the `]` closing the surface list.
    end: Option<usize>,
}

impl SurfaceLayout {
    fn surface_at(&self, line: usize) -> Option<usize> {
        if self.end.is_some_and(|end| line > end) {
            return None;
        }
        self.starts.iter().rposition(|&start| start <= line)
    }

    fn scan(text: &str) -> SurfaceLayout {
        // Bytes, not chars: every byte the scan looks for is ASCII, and UTF-8 never puts an
        // ASCII byte inside a longer character (a Vec<char> held four bytes per byte of text).
        let bytes = text.as_bytes();
        let mut layout = SurfaceLayout::default();
        let mut line = 1;
        let mut depth = 0usize;
        // Depth inside the surface list's brackets, once found.
        let mut list_depth: Option<usize> = None;
        let mut expecting_entry = false;
        let mut surfaces_key_seen = false;
        let mut i = 0;
        while i < bytes.len() {
            let c = bytes[i];
            match c {
                b'\n' => line += 1,
                b'/' if bytes.get(i + 1) == Some(&b'/') => {
                    while i < bytes.len() && bytes[i] != b'\n' {
                        i += 1;
                    }
                    continue;
                }
                b'/' if bytes.get(i + 1) == Some(&b'*') => {
                    i = skip_block_comment(bytes, i, &mut line);
                    continue;
                }
                b'"' => {
                    i = skip_string(bytes, i, &mut line);
                    continue;
                }
                b'r' if matches!(bytes.get(i + 1), Some(b'"' | b'#')) => {
                    i = skip_raw_string(bytes, i + 1, &mut line);
                    continue;
                }
                b'\'' => {
                    // A char literal: 'x' (x one character, of up to four bytes) or '\x'.
                    i = match bytes.get(i + 1) {
                        Some(b'\\') => i + 4,
                        Some(&lead) => i + 2 + utf8_width(lead),
                        None => i + 1,
                    };
                    continue;
                }
                b'(' | b'[' | b'{' => {
                    if list_depth == Some(depth) && expecting_entry {
                        layout.starts.push(line);
                        expecting_entry = false;
                    }
                    depth += 1;
                    if c == b'['
                        && surfaces_key_seen
                        && list_depth.is_none()
                        && layout.end.is_none()
                    {
                        list_depth = Some(depth);
                        expecting_entry = true;
                        surfaces_key_seen = false;
                    }
                }
                b')' | b']' | b'}' => {
                    if list_depth == Some(depth) {
                        layout.end = Some(line);
                        list_depth = None;
                    }
                    depth = depth.saturating_sub(1);
                }
                b',' if list_depth == Some(depth) => expecting_entry = true,
                c if is_identifier_byte(c) && !c.is_ascii_digit() => {
                    let start = i;
                    while i < bytes.len() && is_identifier_byte(bytes[i]) {
                        i += 1;
                    }
                    if list_depth == Some(depth) && expecting_entry {
                        // A named entry such as `Surface(`.
                        layout.starts.push(line);
                        expecting_entry = false;
                    }
                    if depth == 1 && list_depth.is_none() {
                        surfaces_key_seen = &bytes[start..i] == b"surfaces";
                    }
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
        layout
    }
}

/// A byte of an identifier: ASCII letters, digits and `_`, and every byte of a non-ASCII
/// character (RON allows Unicode identifiers; no ASCII byte the scan looks for is among them).
fn is_identifier_byte(byte: u8) -> bool {
    byte.is_ascii_alphanumeric() || byte == b'_' || !byte.is_ascii()
}

/// How many bytes the UTF-8 character that starts with `lead` takes.
fn utf8_width(lead: u8) -> usize {
    match lead.leading_ones() {
        0 => 1,
        n => n as usize,
    }
}

fn skip_block_comment(bytes: &[u8], mut i: usize, line: &mut usize) -> usize {
    // RON block comments nest.
    let mut nesting = 0;
    while i < bytes.len() {
        if bytes[i] == b'/' && bytes.get(i + 1) == Some(&b'*') {
            nesting += 1;
            i += 2;
        } else if bytes[i] == b'*' && bytes.get(i + 1) == Some(&b'/') {
            nesting -= 1;
            i += 2;
            if nesting == 0 {
                return i;
            }
        } else {
            if bytes[i] == b'\n' {
                *line += 1;
            }
            i += 1;
        }
    }
    i
}

fn skip_string(bytes: &[u8], mut i: usize, line: &mut usize) -> usize {
    i += 1;
    while i < bytes.len() {
        match bytes[i] {
            b'\\' => i += 2,
            b'"' => return i + 1,
            b'\n' => {
                *line += 1;
                i += 1;
            }
            _ => i += 1,
        }
    }
    i
}

/// `i` points just after the `r` of `r"..."` or `r#"..."#`.
fn skip_raw_string(bytes: &[u8], mut i: usize, line: &mut usize) -> usize {
    let mut hashes = 0;
    while bytes.get(i) == Some(&b'#') {
        hashes += 1;
        i += 1;
    }
    if bytes.get(i) != Some(&b'"') {
        return i;
    }
    i += 1;
    while i < bytes.len() {
        if bytes[i] == b'"' && (1..=hashes).all(|k| bytes.get(i + k) == Some(&b'#')) {
            return i + 1 + hashes;
        }
        if bytes[i] == b'\n' {
            *line += 1;
        }
        i += 1;
    }
    i
}
