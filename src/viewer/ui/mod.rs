//! The viewer's UI (egui, fed winit's events by egui-winit, drawn by `passes::ui`): each
//! light's shadow method and that method's parameters (listed from the technique registry),
//! each light's direction or position and intensity, the debug view, exposure, samples, the
//! shadow backend, camera bookmarks, the frame's status and a plot of each pass's time. Its
//! controls make `Command`s, applied by the same handler as the script's commands.

mod mesh;
mod panels;

use std::collections::VecDeque;

use winit::event::WindowEvent;
use winit::window::Window;

pub use mesh::{UiAtlas, UiMeshes};

use super::command::{Command, BOOKMARKS};
use super::settings::ViewerSettings;
use crate::scene::Light;

/// Frames of pass times the plot shows.
pub const HISTORY: usize = 300;

/// What the UI shows, gathered by the viewer each frame.
pub struct UiView<'a> {
    pub settings: &'a ViewerSettings,
    pub lights: &'a [Light],
    /// The frame's status: rate, size, scene, playback, accumulation.
    pub status: Vec<String>,
    /// Which bookmarks hold a pose.
    pub bookmarks: [bool; BOOKMARKS],
    /// Whether the device offers ray queries (the ray-query backend).
    pub ray_query: bool,
}

pub struct Ui {
    ctx: egui::Context,
    state: egui_winit::State,
    pub atlas: UiAtlas,
    /// The last `HISTORY` frames' pass times, oldest first.
    history: VecDeque<Vec<(&'static str, f64)>>,
}

impl Ui {
    pub fn new(window: &Window) -> Ui {
        let ctx = egui::Context::default();
        let state = egui_winit::State::new(
            ctx.clone(),
            egui::ViewportId::ROOT,
            window,
            Some(window.scale_factor() as f32),
            None,
            None,
        );
        Ui { ctx, state, atlas: UiAtlas::default(), history: VecDeque::with_capacity(HISTORY) }
    }

    /// Hands a window event to egui; true where egui took it for itself (a click on a control,
    /// a key for a focused field).
    pub fn on_window_event(&mut self, window: &Window, event: &WindowEvent) -> bool {
        self.state.on_window_event(window, event).consumed
    }

    /// Whether keys belong to the UI now (a text or number field is being edited).
    pub fn wants_keyboard(&self) -> bool {
        self.ctx.wants_keyboard_input()
    }

    /// Whether the pointer is over the UI (clicks and the wheel are then the UI's).
    pub fn pointer_over(&self) -> bool {
        self.ctx.is_pointer_over_area() || self.ctx.wants_pointer_input()
    }

    /// One presented frame's pass times, for the plot.
    pub fn record_timings(&mut self, timings: &[(&'static str, f64)]) {
        if timings.is_empty() {
            return;
        }
        if self.history.len() == HISTORY {
            self.history.pop_front();
        }
        self.history.push_back(timings.to_vec());
    }

    /// Lays the UI out for a canvas of `size` pixels: the meshes to draw (the atlas updated)
    /// and the commands its controls gave.
    pub fn frame(&mut self, window: &Window, view: &UiView<'_>, size: [u32; 2]) -> (UiMeshes, Vec<Command>) {
        let input = self.state.take_egui_input(window);
        let mut commands = Vec::new();
        let history = &self.history;
        let output = self.ctx.run(input, |ctx| panels::show(ctx, view, history, &mut commands));
        self.state.handle_platform_output(window, output.platform_output);
        self.atlas.apply(&output.textures_delta);
        let primitives = self.ctx.tessellate(output.shapes, output.pixels_per_point);
        (UiMeshes::new(&primitives, output.pixels_per_point, size), commands)
    }
}
