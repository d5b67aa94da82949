//! Physics models of piezo actuators, shared by the twin (simulation), the fitting
//! objectives, diagnosis and control: one implementation of each model.

pub mod rbf;
