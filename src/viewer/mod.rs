//! `umbra view`: the interactive viewer. The window is a front end over the same renderer and
//! frame graph as capture; input, camera, toggles and scripts are window-system independent.

mod app;
pub mod camera;
mod clock;
pub mod command;
pub mod input;
pub mod interactive;
mod presenter;
pub mod script;
pub mod settings;
mod ui;

pub use app::{run, UiCost, ViewerOptions, ViewerReport};
