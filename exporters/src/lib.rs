//! glint's file-format crate. It knows file formats and nothing of the pipeline: callers hand it plain
//! data (a material description, a tabulated texture), never bake or fit state, so it cannot form a
//! dependency cycle with the root package.
//!
//! Now: [`atomic`] — every file glint writes goes through a temporary file in the destination folder and
//! a rename, so a crash or a full disk never leaves a half-written output; [`npy`] — NumPy arrays for
//! dumped fit problems. The format exporters (EXR table, glTF, USD, MERL) come with their issue.
//!
//! Invariants: no dependency on the `glint` crate; every write is atomic.

pub mod atomic;
pub mod npy;

pub use atomic::{AtomicWriteError, write_atomic};
