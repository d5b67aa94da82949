//! What models are fitted to: recordings read as labs write them, and the drive signals of
//! experiments (and of the twin). Imports only the ground floor.

pub mod recording;
pub mod signal;
