//! The viewer's inputs in its own words, independent of the window system, so scripted input
//! and real input take the same path.

use std::collections::HashSet;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Key {
    W,
    A,
    S,
    D,
    Q,
    E,
    Shift,
    Home,
    F1,
    F12,
    /// Select the next light.
    L,
    /// Cycle the selected light's shadow method.
    T,
    /// Cycle the debug view.
    V,
    /// Switch the shadow backend (compute BVH / ray query).
    B,
    /// Toggle the selected light's traced shadows between soft and hard.
    H,
    /// Cycle the selected light's shadow-map resolution (256 .. 8192).
    R,
    /// Cycle the selected light's PCF radius (0 .. 4).
    P,
    /// Cycle the selected light's depth bias (constant and slope: 0, 1, 2, 4, 8, 16).
    G,
    /// Cycle the selected light's cascade count (1 .. 8).
    C,
    /// Go to camera bookmark 1..4; with Shift held, save the pose there.
    One,
    Two,
    Three,
    Four,
    Plus,
    Minus,
    /// Halve / double the soft-shadow samples.
    BracketLeft,
    BracketRight,
    Escape,
    /// Play or pause a moving scene.
    Space,
    /// Step a moving scene back / on by one frame of `STEP_SECONDS`.
    Comma,
    Period,
}

impl Key {
    pub fn parse(name: &str) -> Option<Key> {
        Some(match name.to_ascii_uppercase().as_str() {
            "W" => Key::W,
            "A" => Key::A,
            "S" => Key::S,
            "D" => Key::D,
            "Q" => Key::Q,
            "E" => Key::E,
            "SHIFT" => Key::Shift,
            "HOME" => Key::Home,
            "F1" => Key::F1,
            "F12" => Key::F12,
            "L" => Key::L,
            "T" => Key::T,
            "V" => Key::V,
            "B" => Key::B,
            "H" => Key::H,
            "R" => Key::R,
            "P" => Key::P,
            "G" => Key::G,
            "C" => Key::C,
            "1" => Key::One,
            "2" => Key::Two,
            "3" => Key::Three,
            "4" => Key::Four,
            "PLUS" | "+" => Key::Plus,
            "MINUS" | "-" => Key::Minus,
            "[" | "BRACKETLEFT" => Key::BracketLeft,
            "]" | "BRACKETRIGHT" => Key::BracketRight,
            "ESCAPE" | "ESC" => Key::Escape,
            "SPACE" => Key::Space,
            "," | "COMMA" => Key::Comma,
            "." | "PERIOD" => Key::Period,
            _ => return None,
        })
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum InputEvent {
    KeyDown(Key),
    /// Auto-repeat of a held key: movement keys are already held, actions ignore it.
    KeyRepeat(Key),
    KeyUp(Key),
    /// Raw pointer motion in counts (only turns the camera while the right button is held).
    MouseMotion {
        dx: f32,
        dy: f32,
    },
    RightButton(bool),
    /// Wheel steps; positive is away from the user.
    Scroll(f32),
    Resize(u32, u32),
    /// Show a moving scene at this many seconds, paused (scripts' `time T`).
    Time(f64),
}

/// Which keys and buttons are held.
#[derive(Clone, Debug, Default)]
pub struct InputState {
    held: HashSet<Key>,
    right_button: bool,
}

impl InputState {
    pub fn apply(&mut self, event: &InputEvent) {
        match *event {
            InputEvent::KeyDown(k) => {
                self.held.insert(k);
            }
            InputEvent::KeyUp(k) => {
                self.held.remove(&k);
            }
            InputEvent::RightButton(b) => self.right_button = b,
            _ => {}
        }
    }

    pub fn held(&self, key: Key) -> bool {
        self.held.contains(&key)
    }

    pub fn looking(&self) -> bool {
        self.right_button
    }
}
