//! Replay scripts (`umbra view --script FILE`) for tests and demos: one command a line, `#`
//! starts a comment.
//!
//! ```text
//! frames 10            # draw 10 frames with the current input (1..=1000000)
//! key down W           # hold a key: W A S D Q E shift home F1 F12 L T V
//!                      # plus minus [ ] esc space , . (any case)
//! key up W
//! press T              # down and up
//! mouse 120 -30        # look: raw motion with the right button held
//! scroll 2             # wheel steps (speed x1.25 each)
//! time 1.5             # a moving scene at 1.5 s, paused (`press space` plays it again)
//! resize 640 480       # 1..=16384 each
//! minimise             # and `restore`
//! screenshot NAME      # NAME.png and NAME.exr beside the scene
//! capture NAME         # NAME.png of exactly what the window shows next, UI included
//! wait_ms 100          # 0..=60000
//! scale 0.5            # moving frames render at this share of each side (0.25..=1);
//!                      # `scale auto` lets the frame-time target choose it again
//! method 0 map         # light 0's shadow method (what the UI's method list sets)
//! param 0 map.resolution 1024   # one parameter of light 0's shadows, as --param names it
//! view albedo          # the debug view, as --debug-view names it (`shaded`: none)
//! exposure 1.5         # EV
//! spp 8                # soft-shadow rays per pixel and frame (1..=64)
//! backend compute      # or ray-query
//! light 0 intensity 2 2 2       # also `direction X Y Z`, `position X Y Z`
//! bookmark save 1      # the camera's pose into bookmark 1 (1..=4); `bookmark 1` goes there
//! open PATH            # a scene file or model in place of the scene (as a dropped file)
//! quit
//! ```

use std::ops::RangeInclusive;
use std::time::Duration;

use super::command::{Command, LightEdit, BOOKMARKS};
use super::input::{InputEvent, Key};

/// Bounds on script arguments: `frames N` takes 1..=MAX_FRAMES, `wait_ms` at most
/// MAX_WAIT_MS, `resize` 1..=MAX_SIZE on each side.
pub const MAX_FRAMES: u64 = 1_000_000;
pub const MAX_WAIT_MS: u64 = 60_000;
pub const MAX_SIZE: u64 = 16_384;

#[derive(Clone, Debug, PartialEq)]
pub enum ScriptStep {
    Frames(u64),
    Input(InputEvent),
    Minimise(bool),
    Screenshot(String),
    /// NAME.png of exactly what the window shows next (UI included).
    Capture(String),
    Wait(Duration),
    /// Moving frames' share of each side, or `None`: chosen by the frame-time target.
    Scale(Option<f32>),
    /// What a UI control does (`command::Command`), through the same handler.
    Command(Command),
    Quit,
}

#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct ScriptError {
    pub file: String,
    pub line: usize,
    pub message: String,
}

pub fn parse(text: &str, file: &str) -> Result<Vec<ScriptStep>, ScriptError> {
    let mut steps = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fail = |message: String| ScriptError { file: file.to_owned(), line: i + 1, message };
        let words: Vec<&str> = line.split_whitespace().collect();
        let number = |w: Option<&&str>, what: &str| -> Result<f32, ScriptError> {
            let w = w.ok_or_else(|| fail(format!("`{}` needs {what}", words[0])))?;
            // Finite as the f32 the input path carries, so 1e300 cannot become infinity.
            w.parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| fail(format!("{w:?} is not a finite number ({what})")))
        };
        // Counts are parsed as integers (never through a float, which would saturate huge
        // values to u64::MAX) and must lie in `range`.
        let count = |w: Option<&&str>, what: &str, range: RangeInclusive<u64>| -> Result<u64, ScriptError> {
            let w = w.ok_or_else(|| fail(format!("`{}` needs {what}", words[0])))?;
            let out_of_range =
                || fail(format!("{what} must be a whole number in {}..={}, not {w}", range.start(), range.end()));
            let digits = w.strip_prefix('+').unwrap_or(w);
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                return Err(out_of_range());
            }
            // All digits: the only parse failure left is overflow, which is out of range too.
            digits.parse::<u64>().ok().filter(|v| range.contains(v)).ok_or_else(out_of_range)
        };
        let key = |w: Option<&&str>| -> Result<Key, ScriptError> {
            let w = w.ok_or_else(|| fail("a key name is missing".into()))?;
            Key::parse(w).ok_or_else(|| fail(format!("unknown key {w:?}")))
        };
        let expect_args = |n: usize| -> Result<(), ScriptError> {
            if words.len() != n + 1 {
                return Err(fail(format!("`{}` takes {n} argument(s), got {}", words[0], words.len() - 1)));
            }
            Ok(())
        };
        match words[0] {
            "frames" => {
                expect_args(1)?;
                steps.push(ScriptStep::Frames(count(words.get(1), "a frame count", 1..=MAX_FRAMES)?));
            }
            "key" => {
                expect_args(2)?;
                let k = key(words.get(2))?;
                steps.push(ScriptStep::Input(match words[1] {
                    "down" => InputEvent::KeyDown(k),
                    "up" => InputEvent::KeyUp(k),
                    other => return Err(fail(format!("`key` takes down or up, not {other:?}"))),
                }));
            }
            "press" => {
                expect_args(1)?;
                let k = key(words.get(1))?;
                steps.extend([ScriptStep::Input(InputEvent::KeyDown(k)), ScriptStep::Input(InputEvent::KeyUp(k))]);
            }
            "mouse" => {
                expect_args(2)?;
                let (dx, dy) = (number(words.get(1), "dx")?, number(words.get(2), "dy")?);
                steps.extend([
                    ScriptStep::Input(InputEvent::RightButton(true)),
                    ScriptStep::Input(InputEvent::MouseMotion { dx, dy }),
                    ScriptStep::Input(InputEvent::RightButton(false)),
                ]);
            }
            "time" => {
                expect_args(1)?;
                let t = number(words.get(1), "seconds")?;
                if t < 0.0 {
                    return Err(fail(format!("time {t}: seconds must be 0 or more")));
                }
                steps.push(ScriptStep::Input(InputEvent::Time(f64::from(t))));
            }
            "scroll" => {
                expect_args(1)?;
                steps.push(ScriptStep::Input(InputEvent::Scroll(number(words.get(1), "wheel steps")?)));
            }
            "resize" => {
                expect_args(2)?;
                // 0x0 is what a minimised window reports: scripts say `minimise` for that.
                let (w, h) = (
                    count(words.get(1), "a width (use `minimise` for 0x0)", 1..=MAX_SIZE)?,
                    count(words.get(2), "a height (use `minimise` for 0x0)", 1..=MAX_SIZE)?,
                );
                steps.push(ScriptStep::Input(InputEvent::Resize(w as u32, h as u32)));
            }
            "minimise" | "minimize" => {
                expect_args(0)?;
                steps.push(ScriptStep::Minimise(true));
            }
            "restore" => {
                expect_args(0)?;
                steps.push(ScriptStep::Minimise(false));
            }
            "screenshot" | "capture" => {
                expect_args(1)?;
                let name = words[1];
                if !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) || name.starts_with('.') {
                    return Err(fail(format!("{} name {name:?} may hold only letters, digits, - _ .", words[0])));
                }
                steps.push(if words[0] == "screenshot" {
                    ScriptStep::Screenshot(name.to_owned())
                } else {
                    ScriptStep::Capture(name.to_owned())
                });
            }
            "wait_ms" => {
                expect_args(1)?;
                let ms = count(words.get(1), "milliseconds", 0..=MAX_WAIT_MS)?;
                steps.push(ScriptStep::Wait(Duration::from_millis(ms)));
            }
            "scale" => {
                expect_args(1)?;
                let share = match words[1] {
                    "auto" => None,
                    _ => Some(number(words.get(1), "a share of each side, or auto")?),
                };
                let range = super::interactive::MIN_SCALE..=1.0;
                if let Some(s) = share.filter(|s| !range.contains(s)) {
                    return Err(fail(format!("scale {s}: a share of each side in 0.25..=1, or auto")));
                }
                steps.push(ScriptStep::Scale(share));
            }
            "quit" => {
                expect_args(0)?;
                steps.push(ScriptStep::Quit);
            }
            "method" => {
                expect_args(2)?;
                let light = count(words.get(1), "a light index", 0..=u32::MAX as u64)? as usize;
                let method =
                    super::command::method(words[2]).ok_or_else(|| fail(format!("unknown method {:?}", words[2])))?;
                steps.push(ScriptStep::Command(Command::Method { light, method }));
            }
            "param" => {
                expect_args(3)?;
                let light = count(words.get(1), "a light index", 0..=u32::MAX as u64)? as usize;
                let (key, value) = (words[2].to_owned(), words[3].to_owned());
                steps.push(ScriptStep::Command(Command::Param { light, key, value }));
            }
            "view" => {
                expect_args(1)?;
                steps.push(ScriptStep::Command(Command::View(words[1].to_owned())));
            }
            "exposure" => {
                expect_args(1)?;
                steps.push(ScriptStep::Command(Command::Exposure(number(words.get(1), "EV")?)));
            }
            "spp" => {
                expect_args(1)?;
                let n = count(words.get(1), "rays per pixel", 1..=u64::from(super::settings::MAX_SPP))?;
                steps.push(ScriptStep::Command(Command::Spp(n as u32)));
            }
            "backend" => {
                expect_args(1)?;
                let b = super::command::backend(words[1])
                    .ok_or_else(|| fail(format!("backend {:?}: compute or ray-query", words[1])))?;
                steps.push(ScriptStep::Command(Command::Backend(b)));
            }
            "light" => {
                expect_args(5)?;
                let light = count(words.get(1), "a light index", 0..=u32::MAX as u64)? as usize;
                let v =
                    glam::Vec3::new(number(words.get(3), "x")?, number(words.get(4), "y")?, number(words.get(5), "z")?);
                let edit = match words[2] {
                    "intensity" => LightEdit::Intensity(v),
                    "direction" => LightEdit::Direction(v),
                    "position" => LightEdit::Position(v.as_dvec3()),
                    other => return Err(fail(format!("`light` sets intensity, direction or position, not {other:?}"))),
                };
                steps.push(ScriptStep::Command(Command::Light { light, edit }));
            }
            "bookmark" => {
                let save = words.get(1) == Some(&"save");
                expect_args(if save { 2 } else { 1 })?;
                let slot = count(words.get(if save { 2 } else { 1 }), "a bookmark", 1..=BOOKMARKS as u64)? as usize - 1;
                steps.push(ScriptStep::Command(Command::Bookmark { slot, save }));
            }
            "open" => {
                // The rest of the line, so a path may hold spaces.
                let path = line["open".len()..].trim();
                if path.is_empty() {
                    return Err(fail("`open` needs a path".into()));
                }
                steps.push(ScriptStep::Command(Command::Open(path.into())));
            }
            other => return Err(fail(format!("unknown command {other:?}"))),
        }
    }
    Ok(steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ui_commands_parse_to_the_handlers_commands() {
        let text = "method 1 map\nparam 0 map.resolution 1024\nview albedo\nexposure -1.5\nspp 8\n\
                    backend ray-query\nlight 2 direction 0 -1 0\nbookmark save 2\nbookmark 4\nopen a b.obj # c\n";
        let steps = parse(text, "s").unwrap();
        let commands: Vec<Command> = steps
            .into_iter()
            .map(|s| match s {
                ScriptStep::Command(c) => c,
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(commands[0], Command::Method { light: 1, method: crate::config::ShadowMethod::Map });
        assert_eq!(commands[1], Command::Param { light: 0, key: "map.resolution".into(), value: "1024".into() });
        assert_eq!(commands[2], Command::View("albedo".into()));
        assert_eq!(commands[3], Command::Exposure(-1.5));
        assert_eq!(commands[4], Command::Spp(8));
        assert_eq!(commands[5], Command::Backend(crate::config::ShadowBackend::RayQuery));
        assert_eq!(commands[6], Command::Light { light: 2, edit: LightEdit::Direction(glam::Vec3::NEG_Y) });
        assert_eq!(commands[7], Command::Bookmark { slot: 1, save: true });
        assert_eq!(commands[8], Command::Bookmark { slot: 3, save: false });
        assert_eq!(commands[9], Command::Open("a b.obj".into()));
        for bad in ["method 0 fast", "spp 0", "bookmark 5", "light 0 colour 1 1 1", "backend gpu", "open"] {
            assert!(parse(bad, "s").is_err(), "{bad}");
        }
    }

    #[test]
    fn a_script_parses_to_steps() {
        let steps = parse("# demo\nframes 3\npress T\nkey down w # hold\nmouse 10 -5\nresize 64 48\nminimise\nrestore\nscreenshot a-1\nwait_ms 5\nquit\n", "s").unwrap();
        assert_eq!(steps[0], ScriptStep::Frames(3));
        assert_eq!(steps[1], ScriptStep::Input(InputEvent::KeyDown(Key::T)));
        assert_eq!(steps[2], ScriptStep::Input(InputEvent::KeyUp(Key::T)));
        assert_eq!(steps[3], ScriptStep::Input(InputEvent::KeyDown(Key::W)));
        assert_eq!(steps[5], ScriptStep::Input(InputEvent::MouseMotion { dx: 10.0, dy: -5.0 }));
        assert_eq!(steps[7], ScriptStep::Input(InputEvent::Resize(64, 48)));
        assert_eq!(steps[8], ScriptStep::Minimise(true));
        assert_eq!(steps[10], ScriptStep::Screenshot("a-1".into()));
        assert_eq!(steps.last(), Some(&ScriptStep::Quit));
    }

    #[test]
    fn errors_name_the_file_and_line() {
        let err = |t: &str| parse(t, "demo.txt").unwrap_err().to_string();
        assert_eq!(err("frames 2\nfly 3"), "demo.txt:2: unknown command \"fly\"");
        assert_eq!(err("press X"), "demo.txt:1: unknown key \"X\"");
        assert!(err("frames -1").contains("whole number"));
        assert!(err("resize 0 10").contains("minimise"));
        assert!(err("scale 0.1").contains("0.25..=1"));
        assert!(err("scale big").contains("not a finite number"));
        assert_eq!(
            parse("scale 0.5\nscale auto", "s").unwrap(),
            [ScriptStep::Scale(Some(0.5)), ScriptStep::Scale(None)]
        );
        assert!(err("time -1").contains("0 or more"), "{}", err("time -1"));
        assert_eq!(parse("time 1.5\npress space", "s").unwrap()[0], ScriptStep::Input(InputEvent::Time(1.5)));
        assert!(err("screenshot ../x").contains("letters"));
        assert!(err("key sideways W").contains("down or up"));
        assert!(err("mouse 1").contains("takes 2 argument"));
    }

    #[test]
    fn counts_are_integers_within_bounds() {
        let err = |t: &str| parse(t, "s").unwrap_err().to_string();
        let ok = |t: &str| parse(t, "s").unwrap();
        // Used to go through f64 and saturate to u64::MAX frames.
        assert!(err("frames 1e30").contains("whole number"));
        assert!(err("frames 18446744073709551616").contains("1..=1000000"), "u64 overflow");
        assert!(err("frames 99999999999999999999999").contains("1..=1000000"));
        assert!(err("frames 0").contains("1..=1000000"), "zero frames would be a no-op");
        assert!(err("frames 1000001").contains("1..=1000000"));
        assert!(err("frames 2.5").contains("whole number"));
        assert!(err("frames 2.0").contains("whole number"));
        assert!(err("frames inf").contains("whole number"));
        assert!(err("frames NaN").contains("whole number"));
        assert!(err("frames -0").contains("whole number"));
        assert!(err("frames +").contains("whole number"));
        assert_eq!(ok("frames 1"), vec![ScriptStep::Frames(1)]);
        assert_eq!(ok("frames +7"), vec![ScriptStep::Frames(7)]);
        assert_eq!(ok("frames 1000000"), vec![ScriptStep::Frames(MAX_FRAMES)]);

        assert!(err("wait_ms 60001").contains("0..=60000"));
        assert!(err("wait_ms 1e9").contains("whole number"));
        assert!(err("wait_ms -5").contains("whole number"));
        assert_eq!(ok("wait_ms 0"), vec![ScriptStep::Wait(Duration::ZERO)]);
        assert_eq!(ok("wait_ms 60000"), vec![ScriptStep::Wait(Duration::from_secs(60))]);

        assert!(err("resize 16385 10").contains("1..=16384"));
        assert!(err("resize 10 4294967296").contains("1..=16384"), "would wrap to 0 as u32");
        assert!(err("resize 64.0 48").contains("whole number"));
        assert_eq!(ok("resize 16384 1"), vec![ScriptStep::Input(InputEvent::Resize(16384, 1))]);
    }

    #[test]
    fn motion_and_wheel_must_be_finite() {
        let err = |t: &str| parse(t, "s").unwrap_err().to_string();
        assert!(err("mouse NaN 0").contains("finite"));
        assert!(err("mouse 0 inf").contains("finite"));
        assert!(err("mouse 1e300 0").contains("finite"), "overflows f32");
        assert!(err("scroll -inf").contains("finite"));
        assert!(err("scroll 1e39").contains("finite"));
        assert!(err("scroll").contains("takes 1 argument"));
        assert_eq!(parse("scroll -2.5", "s").unwrap(), vec![ScriptStep::Input(InputEvent::Scroll(-2.5))]);
    }

    #[test]
    fn comments_blank_lines_and_key_names() {
        let text = "\n   \n# only a comment\npress ] # double spp\npress [\npress esc\nkey up SHIFT\n";
        let steps = parse(text, "s").unwrap();
        assert_eq!(
            steps,
            vec![
                ScriptStep::Input(InputEvent::KeyDown(Key::BracketRight)),
                ScriptStep::Input(InputEvent::KeyUp(Key::BracketRight)),
                ScriptStep::Input(InputEvent::KeyDown(Key::BracketLeft)),
                ScriptStep::Input(InputEvent::KeyUp(Key::BracketLeft)),
                ScriptStep::Input(InputEvent::KeyDown(Key::Escape)),
                ScriptStep::Input(InputEvent::KeyUp(Key::Escape)),
                ScriptStep::Input(InputEvent::KeyUp(Key::Shift)),
            ]
        );
        let err = |t: &str| parse(t, "s").unwrap_err().to_string();
        assert!(err("quit now").contains("takes 0 argument"));
        assert!(err("frames 1 2").contains("takes 1 argument"));
        assert!(err("screenshot .hidden").contains("letters"));
        assert!(err("\n\nwait_ms 70000").starts_with("s:3: "));
    }
}
