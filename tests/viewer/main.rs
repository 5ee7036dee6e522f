//! The viewer under Xvfb on lavapipe: scripted input, screenshots, hardening and a memory
//! soak, one viewer at a time (`common::XVFB`).
//!
//! One test binary (one link of umbra) whose modules share `common`. The suite has three:
//! `cpu`, `gpu` and `viewer`; `cargo test --release --test gpu stress_scenes::` runs one module.

#[path = "../common/mod.rs"]
mod common;

mod soak;
mod ui;
mod viewer;
mod viewer_hardening;
