//! The ground floor: what every other module may use and which uses nothing of the
//! project. Random streams and their seeds with the one stable hash, atomic file writing,
//! errors, JSON numbers that may be infinite, names safe as path components, the
//! declarative parameter tables of objectives and optimizers, and the upper limits on sizes
//! a user can set.

pub mod atomic;
pub mod error;
pub mod hash;
pub mod json_float;
pub mod limits;
pub mod lstsq;
pub mod name;
pub mod params;
pub mod seed;

pub use atomic::{atomic_write, create_dir_within, remove_stale_temporaries};
pub use name::SafeName;
pub use seed::{TrialSeed, standard_normal};
