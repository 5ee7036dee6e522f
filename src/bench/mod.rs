//! `umbra bench`: sweeps of shadow methods, scored against a traced reference.

pub mod metrics;
