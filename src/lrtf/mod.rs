//! Lens ray transfer function (LRTF) tables: bake the exact film-to-scene transfer of a
//! rotationally symmetric lens into a 3D table of 8 channels, store it as OpenEXR + RON sidecar,
//! and sample it exactly the way the renderer's shader does. Design and file layout: docs/lrtf.md.

pub mod bake;
pub mod binding;
pub mod entries;
pub mod focus;
pub mod io;
pub mod measure;
pub mod param;
pub mod table;

pub use binding::{BindingError, EngineBinding};
pub use entries::Entries;
pub use focus::{FocusError, FocusRange};
pub use param::{Frame, Parameterisation, Ray, Transfer};
pub use table::{
    Corners, FocusedTable, GpuParams, Layer, Lookup, LookupError, LrtfTable, Precision, TableInfo,
};
#[cfg(feature = "render")]
pub(crate) use table::{LOOKUP_GROUP, LookupScratch};
