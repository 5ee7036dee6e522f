//! `umbra bench`: sweeps of shadow methods, scored against a traced reference.
//!
//! - `auto`: the calibration that picks each `auto` light's method;
//! - `metrics`: the error metrics (visibility RMSE, leak, false shadow, FLIP) and the Pareto front;
//! - `sweep`: methods and the points of their sweeps;
//! - `reference`: the traced reference per light and frame, and its cache;
//! - `shadows`: the run itself (`umbra bench shadows`);
//! - `score`: one point's rows: its visibility and frame scored, a denoised light after its history;
//! - `rays`: the ray benchmark (`umbra bench rays`): device traversals against obvhs on the CPU;
//! - `report`: rows as CSV and JSON, the summary table;
//! - `chart`: time against error per scene, SVG and PNG.

pub mod auto;
pub mod chart;
pub mod errors;
pub mod merge;
pub mod metrics;
pub mod motion;
pub mod rays;
pub mod reference;
pub mod report;
pub mod score;
pub mod shadows;
pub mod sweep;
