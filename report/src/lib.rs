//! Figures and metrics of simulation results: an SVG plotter and the case-study measures.
//!
//! Results reach this crate through [`Columns`], so it does not depend on the master that
//! produced them (the master's `Table` implements it, and so can a CSV reader).

pub mod casestudy;
pub mod plot;

/// Named columns of simulation results (`time` among them).
pub trait Columns {
    /// The column names, in order.
    fn names(&self) -> &[String];
    /// The values of column `name`.
    fn column(&self, name: &str) -> Option<Vec<f64>>;
}
