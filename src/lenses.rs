//! Lenses bundled with lensbake, embedded in the binary so a name works from any directory.

/// A bundled lens: its short name and its canonical RON text.
#[derive(Clone, Copy, Debug)]
pub struct BundledLens {
    pub name: &'static str,
    pub ron: &'static str,
}

/// Every bundled lens, sorted by name. The files live in `lenses/<name>.ron`.
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
        name: "reflex-1000mm-f7.5",
        ron: include_str!("../lenses/reflex-1000mm-f7.5.ron"),
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

// The loader: a lens named by a file path or by a bundled lens's name.

use crate::prescription::formats::{Format, LoadOptions, Loaded, read_file, read_str};
use crate::prescription::{Location, PrescriptionError, Problem, StopShape};
use crate::system::LensSystem;
use std::fmt;
use std::path::{Path, PathBuf};

/// The bundled lens called `name`.
pub fn find(name: &str) -> Option<&'static BundledLens> {
    BUNDLED.iter().find(|lens| lens.name == name)
}

/// Where a lens came from.
#[derive(Clone, Debug, PartialEq)]
pub enum LensOrigin {
    File(PathBuf),
    Bundled(&'static str),
}

impl LensOrigin {
    /// Short name for reports and output folders: the bundled name, or the file's stem.
    pub fn name(&self) -> String {
        match self {
            LensOrigin::File(path) => path.file_stem().map_or_else(
                || path.display().to_string(),
                |stem| stem.to_string_lossy().into_owned(),
            ),
            LensOrigin::Bundled(name) => (*name).to_string(),
        }
    }
}

impl fmt::Display for LensOrigin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LensOrigin::File(path) => write!(f, "{}", path.display()),
            LensOrigin::Bundled(name) => write!(f, "bundled lens `{name}`"),
        }
    }
}

/// A lens as read, before validation.
#[derive(Clone, Debug, PartialEq)]
pub struct LensSource {
    pub origin: LensOrigin,
    pub loaded: Loaded,
}

/// A lens read and validated into a system.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedLens {
    pub source: LensSource,
    pub system: LensSystem,
}

impl LoadedLens {
    /// The shape of the aperture stop (None for a lens without one).
    pub fn stop_shape(&self) -> Option<&StopShape> {
        self.system
            .prescription
            .surfaces
            .iter()
            .find_map(|s| s.stop.as_ref())
    }

    /// This lens with its aperture stop's shape replaced: round, or a diaphragm of blades (the
    /// shape of its bokeh in a traced or baked render). Validated as a lens file stating it
    /// would be (at least three blades, curvature 0 to 1).
    ///
    /// ```
    /// use lensbake::lenses;
    /// use lensbake::prescription::StopShape;
    /// use lensbake::prescription::formats::LoadOptions;
    /// let lens = lenses::load("dgauss-50mm", &LoadOptions::default()).unwrap();
    /// let five = StopShape::Blades { count: 5, rotation_deg: 0.0, blade_curvature: 0.0 };
    /// assert_eq!(lens.with_stop_shape(five.clone()).unwrap().stop_shape(), Some(&five));
    /// let two = StopShape::Blades { count: 2, rotation_deg: 0.0, blade_curvature: 0.0 };
    /// assert!(lens.with_stop_shape(two).is_err());
    /// ```
    pub fn with_stop_shape(&self, shape: StopShape) -> Result<LoadedLens, PrescriptionError> {
        let mut prescription = self.system.prescription.clone();
        for surface in &mut prescription.surfaces {
            if surface.stop.is_some() {
                surface.stop = Some(shape.clone());
            }
        }
        Ok(LoadedLens {
            source: self.source.clone(),
            system: LensSystem::from_prescription(prescription)?,
        })
    }
}

#[derive(Debug, thiserror::Error)]
pub enum LensError {
    #[error(transparent)]
    Prescription(#[from] PrescriptionError),
    #[error("`{spec}` is neither a lens file nor a bundled lens; bundled lenses: {}", list(.bundled))]
    NotFound {
        spec: String,
        bundled: Vec<&'static str>,
    },
}

fn list(names: &[&str]) -> String {
    if names.is_empty() {
        "(none)".to_string()
    } else {
        names.join(", ")
    }
}

/// Reads the lens `spec` names: an existing file (format from `options` or its extension), or
/// else a bundled lens by name. A file wins over a bundled lens of the same name.
pub fn read(spec: &str, options: &LoadOptions) -> Result<LensSource, LensError> {
    let path = Path::new(spec);
    if path.exists() {
        return Ok(LensSource {
            origin: LensOrigin::File(path.to_path_buf()),
            loaded: read_file(path, options)?,
        });
    }
    let Some(lens) = find(spec) else {
        return Err(LensError::NotFound {
            spec: spec.to_string(),
            bundled: BUNDLED.iter().map(|l| l.name).collect(),
        });
    };
    let label = PathBuf::from(format!("lenses/{}.ron", lens.name));
    if let Some(format) = options.format.filter(|f| *f != Format::Ron) {
        return Err(PrescriptionError::new(
            Location::file(&label),
            Problem::Unsupported(format!(
                "bundled lenses are RON; they cannot be read as {format}"
            )),
        )
        .into());
    }
    Ok(LensSource {
        origin: LensOrigin::Bundled(lens.name),
        loaded: read_str(lens.ron, Some(&label), Format::Ron, options)?,
    })
}

/// Reads and validates the lens `spec` names (see [`read`]).
pub fn load(spec: &str, options: &LoadOptions) -> Result<LoadedLens, LensError> {
    let source = read(spec, options)?;
    let system = LensSystem::new(source.loaded.prescription.clone(), &source.loaded.map)?;
    Ok(LoadedLens { source, system })
}

/// Why a lens could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteLensError {
    #[error("{}: the output must be a .ron, .zmx or .dat (pbrt) file", .0.display())]
    Format(PathBuf),
    #[error("cannot write {} as {what}", path.display())]
    Cannot {
        path: PathBuf,
        what: &'static str,
        #[source]
        problem: Problem,
    },
    /// The lens states a condition its readers refuse (`lensbake lens check` refuses it too):
    /// a file written with it could not be read back.
    #[error("cannot write {}: {error}", path.display())]
    StatedCondition {
        path: PathBuf,
        #[source]
        error: Box<crate::analysis::AnalysisError>,
    },
    /// The text that would be written is one lensbake's own reader refuses; nothing is written.
    #[error("cannot write {}: the {what} would be refused when read back: {error}", path.display())]
    Unreadable {
        path: PathBuf,
        what: &'static str,
        #[source]
        error: PrescriptionError,
    },
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    #[error(transparent)]
    Prescription(#[from] PrescriptionError),
}

/// Writes `system` to `path` in the format its extension names: lensbake RON (`.ron`), Zemax
/// (`.zmx`: the conditions the lens is analysed under become its aperture and fields, since a
/// Zemax file holds no claims) or pbrt (`.dat`: one index per medium, at the design
/// wavelength). Returns the format written.
///
/// ```
/// use lensbake::lenses::write_lens;
/// use lensbake::{LoadOptions, load_lens};
///
/// let lens = load_lens("cooke-triplet", &LoadOptions::default())?;
/// let path = std::env::temp_dir().join(format!("lensbake-doc-{}.zmx", std::process::id()));
/// write_lens(&lens.system, &path)?;
/// let back = load_lens(path.to_str().unwrap(), &LoadOptions::default())?;
/// assert_eq!(back.system.prescription.surfaces.len(), 6);
/// std::fs::remove_file(&path)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_lens(system: &LensSystem, path: &Path) -> Result<Format, WriteLensError> {
    use crate::analysis::{AnalysisError, ConditionOverrides, DesignConditions};
    use crate::prescription::formats::{write_pbrt, write_ron, write_zemax};
    let cannot = |what| {
        move |problem| WriteLensError::Cannot {
            path: path.to_path_buf(),
            what,
            problem,
        }
    };
    // The conditions `lensbake lens check` refuses (an entrance pupil of 1e300 mm, an object
    // at distance 0, a 90 degree field) are refused here, naming where the input states them.
    if let Err(error @ AnalysisError::Stated { .. }) =
        DesignConditions::resolve(system, &ConditionOverrides::default())
    {
        return Err(WriteLensError::StatedCondition {
            path: path.to_path_buf(),
            error: Box::new(error),
        });
    }
    let format = Format::from_path(path).map_err(|_| WriteLensError::Format(path.to_path_buf()))?;
    let (text, what) = match format {
        Format::Zemax => {
            let stated = crate::analysis::stated_as_analysed(system);
            (
                write_zemax(&stated).map_err(cannot("a Zemax file"))?,
                "Zemax file",
            )
        }
        Format::Pbrt => {
            let nm = system.design_wavelength_nm();
            let text = write_pbrt(&system.prescription, nm).map_err(cannot("a pbrt lens file"))?;
            (text, "pbrt lens file")
        }
        Format::Ron => (write_ron(&system.prescription), "RON file"),
        _ => return Err(WriteLensError::Format(path.to_path_buf())),
    };
    readable_back(&text, path, format).map_err(|error| WriteLensError::Unreadable {
        path: path.to_path_buf(),
        what,
        error,
    })?;
    crate::output::write_bytes(path, text.as_bytes())?;
    Ok(format)
}

/// Reads `text` back as `path`'s reader would and validates it as `lensbake lens check` does,
/// so a file lensbake writes is always one it reads.
fn readable_back(text: &str, path: &Path, format: Format) -> Result<(), PrescriptionError> {
    use crate::analysis::{AnalysisError, ConditionOverrides, DesignConditions};
    let loaded = read_str(text, Some(path), format, &LoadOptions::default())?;
    let system = LensSystem::new(loaded.prescription, &loaded.map)?;
    match DesignConditions::resolve(&system, &ConditionOverrides::default()) {
        Err(AnalysisError::Stated { at, error, .. }) => Err(PrescriptionError::new(
            at,
            Problem::Unsupported(error.to_string()),
        )),
        _ => Ok(()),
    }
}
