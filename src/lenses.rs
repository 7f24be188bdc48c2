//! Lenses bundled with lensbake, embedded in the binary so a name works from any directory.

/// A bundled lens: its short name and its canonical RON text.
#[derive(Clone, Copy, Debug)]
pub struct BundledLens {
    pub name: &'static str,
    pub ron: &'static str,
}

/// Every bundled lens, sorted by name. The files live in lenses/<name>.ron.
pub const BUNDLED: &[BundledLens] = &[
    BundledLens {
        name: "asph-50mm-f1.8",
        ron: include_str!("../lenses/asph-50mm-f1.8.ron"),
    },
    BundledLens {
        name: "biconvex-singlet",
        ron: include_str!("../lenses/biconvex-singlet.ron"),
    },
    BundledLens {
        name: "codev-dgauss-f2",
        ron: include_str!("../lenses/codev-dgauss-f2.ron"),
    },
    BundledLens {
        name: "cooke-triplet",
        ron: include_str!("../lenses/cooke-triplet.ron"),
    },
    BundledLens {
        name: "dgauss-50mm",
        ron: include_str!("../lenses/dgauss-50mm.ron"),
    },
    BundledLens {
        name: "fisheye-10mm",
        ron: include_str!("../lenses/fisheye-10mm.ron"),
    },
    BundledLens {
        name: "kolb-dgauss",
        ron: include_str!("../lenses/kolb-dgauss.ron"),
    },
    BundledLens {
        name: "petzval",
        ron: include_str!("../lenses/petzval.ron"),
    },
    BundledLens {
        name: "telephoto-250mm",
        ron: include_str!("../lenses/telephoto-250mm.ron"),
    },
    BundledLens {
        name: "tessar",
        ron: include_str!("../lenses/tessar.ron"),
    },
    BundledLens {
        name: "wide-22mm",
        ron: include_str!("../lenses/wide-22mm.ron"),
    },
];
