//! Lenses bundled with lensbake, embedded in the binary so a name works from any directory.

/// A bundled lens: its short name and its canonical RON text.
#[derive(Clone, Copy, Debug)]
pub struct BundledLens {
    pub name: &'static str,
    pub ron: &'static str,
}

/// Every bundled lens, sorted by name. The files live in lenses/<name>.ron.
pub const BUNDLED: &[BundledLens] = &[];
