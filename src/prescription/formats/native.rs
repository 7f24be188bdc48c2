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
        let chars: Vec<char> = text.chars().collect();
        let mut layout = SurfaceLayout::default();
        let mut line = 1;
        let mut depth = 0usize;
        // Depth inside the surface list's brackets, once found.
        let mut list_depth: Option<usize> = None;
        let mut expecting_entry = false;
        let mut surfaces_key_seen = false;
        let mut i = 0;
        while i < chars.len() {
            let c = chars[i];
            match c {
                '\n' => line += 1,
                '/' if chars.get(i + 1) == Some(&'/') => {
                    while i < chars.len() && chars[i] != '\n' {
                        i += 1;
                    }
                    continue;
                }
                '/' if chars.get(i + 1) == Some(&'*') => {
                    i = skip_block_comment(&chars, i, &mut line);
                    continue;
                }
                '"' => {
                    i = skip_string(&chars, i, &mut line);
                    continue;
                }
                'r' if matches!(chars.get(i + 1), Some('"' | '#')) => {
                    i = skip_raw_string(&chars, i + 1, &mut line);
                    continue;
                }
                '\'' => {
                    // A char literal: 'x' or '\x'.
                    i += if chars.get(i + 1) == Some(&'\\') {
                        4
                    } else {
                        3
                    };
                    continue;
                }
                '(' | '[' | '{' => {
                    if list_depth == Some(depth) && expecting_entry {
                        layout.starts.push(line);
                        expecting_entry = false;
                    }
                    depth += 1;
                    if c == '[' && surfaces_key_seen && list_depth.is_none() && layout.end.is_none()
                    {
                        list_depth = Some(depth);
                        expecting_entry = true;
                        surfaces_key_seen = false;
                    }
                }
                ')' | ']' | '}' => {
                    if list_depth == Some(depth) {
                        layout.end = Some(line);
                        list_depth = None;
                    }
                    depth = depth.saturating_sub(1);
                }
                ',' if list_depth == Some(depth) => expecting_entry = true,
                c if c.is_alphabetic() || c == '_' => {
                    let start = i;
                    while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                        i += 1;
                    }
                    if list_depth == Some(depth) && expecting_entry {
                        // A named entry such as `Surface(`.
                        layout.starts.push(line);
                        expecting_entry = false;
                    }
                    let word: String = chars[start..i].iter().collect();
                    if depth == 1 && list_depth.is_none() {
                        surfaces_key_seen = word == "surfaces";
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

fn skip_block_comment(chars: &[char], mut i: usize, line: &mut usize) -> usize {
    // RON block comments nest.
    let mut nesting = 0;
    while i < chars.len() {
        if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
            nesting += 1;
            i += 2;
        } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
            nesting -= 1;
            i += 2;
            if nesting == 0 {
                return i;
            }
        } else {
            if chars[i] == '\n' {
                *line += 1;
            }
            i += 1;
        }
    }
    i
}

fn skip_string(chars: &[char], mut i: usize, line: &mut usize) -> usize {
    i += 1;
    while i < chars.len() {
        match chars[i] {
            '\\' => i += 2,
            '"' => return i + 1,
            '\n' => {
                *line += 1;
                i += 1;
            }
            _ => i += 1,
        }
    }
    i
}

/// `i` points just after the `r` of `r"..."` or `r#"..."#`.
fn skip_raw_string(chars: &[char], mut i: usize, line: &mut usize) -> usize {
    let mut hashes = 0;
    while chars.get(i) == Some(&'#') {
        hashes += 1;
        i += 1;
    }
    if chars.get(i) != Some(&'"') {
        return i;
    }
    i += 1;
    while i < chars.len() {
        if chars[i] == '"' && (1..=hashes).all(|k| chars.get(i + k) == Some(&'#')) {
            return i + 1 + hashes;
        }
        if chars[i] == '\n' {
            *line += 1;
        }
        i += 1;
    }
    i
}
