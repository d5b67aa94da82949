//! What optbench shows people: terminal tables now; plots and paper tables build on the
//! same stored results.

pub mod font;
pub mod plots;
pub mod table;
