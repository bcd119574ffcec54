//! The model folder on disk: what `farma fit -o DIR` (and `farma update`, `farma
//! analyze`) write, and what `check`, `update` and the simulator read back.
//!
//! | file | what | written by |
//! |---|---|---|
//! | `params.parquet` | one row per channel: order, b, mean, sigma2, bandwidth, ... | fit, update, analyze |
//! | `coef.parquet` | one row per channel, m and grid point: f, slope, se, ... | fit, update, analyze |
//! | `gcv.parquet` | the GCV table of each channel | fit, update, analyze |
//! | `residuals.parquet` | residuals (`--residuals`) | fit, update |
//! | `state.parquet` | the online normal equations (`--save-state`) | fit, update |
//!
//! The columns are documented in the README ("farma fit"). A fit with a 2-D index
//! records `index` and `index2` in the metadata of its params.parquet.
//!
//! [`tables`] builds the tables (and the `--json` object of a model), [`state_file`]
//! writes and reads state.parquet, and [`ModelDir`] reads a channel's model back.

mod read;
pub mod state_file;
pub mod tables;

use std::path::{Path, PathBuf};

/// One row per fitted channel.
pub const PARAMS_FILE: &str = "params.parquet";
/// The coefficient functions at the grid points.
pub const COEF_FILE: &str = "coef.parquet";
/// The GCV tables.
pub const GCV_FILE: &str = "gcv.parquet";
/// Residuals of the fitted (or new) samples.
pub const RESIDUALS_FILE: &str = "residuals.parquet";
/// The state an online update continues from.
pub const STATE_FILE: &str = "state.parquet";

/// Every file a fit or an update can write into its folder: a run removes those of
/// an earlier run that it does not write.
pub const FIT_OUTPUTS: [&str; 5] = [COEF_FILE, PARAMS_FILE, GCV_FILE, RESIDUALS_FILE, STATE_FILE];

/// A model folder.
#[derive(Clone, Debug)]
pub struct ModelDir {
    path: PathBuf,
}

impl ModelDir {
    pub fn new(path: impl Into<PathBuf>) -> ModelDir {
        ModelDir { path: path.into() }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn params_path(&self) -> PathBuf {
        self.path.join(PARAMS_FILE)
    }

    pub fn coef_path(&self) -> PathBuf {
        self.path.join(COEF_FILE)
    }

    pub fn state_path(&self) -> PathBuf {
        self.path.join(STATE_FILE)
    }
}
