//! Replay scripts (`umbra view --script FILE`) for tests and demos: one command a line, `#`
//! starts a comment.
//!
//! ```text
//! frames 10            # draw 10 frames with the current input
//! key down W           # hold a key (W A S D Q E shift home F1 F12 L T V plus minus)
//! key up W
//! press T              # down and up
//! mouse 120 -30        # look: raw motion with the right button held
//! scroll 2             # wheel steps (speed x1.25 each)
//! resize 640 480
//! minimise             # and `restore`
//! screenshot NAME      # NAME.png and NAME.exr beside the scene
//! wait_ms 100
//! quit
//! ```

use std::time::Duration;

use super::input::{InputEvent, Key};

#[derive(Clone, Debug, PartialEq)]
pub enum ScriptStep {
    Frames(u64),
    Input(InputEvent),
    Minimise(bool),
    Screenshot(String),
    Wait(Duration),
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
        let number = |w: Option<&&str>, what: &str| -> Result<f64, ScriptError> {
            let w = w.ok_or_else(|| fail(format!("`{}` needs {what}", words[0])))?;
            w.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| fail(format!("{w:?} is not a number ({what})")))
        };
        let count = |w: Option<&&str>, what: &str| -> Result<u64, ScriptError> {
            let v = number(w, what)?;
            if v < 0.0 || v.fract() != 0.0 {
                return Err(fail(format!("{what} must be a whole number >= 0, not {v}")));
            }
            Ok(v as u64)
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
                steps.push(ScriptStep::Frames(count(words.get(1), "a frame count")?));
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
                let (dx, dy) = (number(words.get(1), "dx")? as f32, number(words.get(2), "dy")? as f32);
                steps.extend([
                    ScriptStep::Input(InputEvent::RightButton(true)),
                    ScriptStep::Input(InputEvent::MouseMotion { dx, dy }),
                    ScriptStep::Input(InputEvent::RightButton(false)),
                ]);
            }
            "scroll" => {
                expect_args(1)?;
                steps.push(ScriptStep::Input(InputEvent::Scroll(number(words.get(1), "wheel steps")? as f32)));
            }
            "resize" => {
                expect_args(2)?;
                let (w, h) = (count(words.get(1), "a width")?, count(words.get(2), "a height")?);
                if w == 0 || h == 0 || w > 16384 || h > 16384 {
                    return Err(fail(format!("size {w}x{h} must be 1..=16384 each (use `minimise` for 0x0)")));
                }
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
            "screenshot" => {
                expect_args(1)?;
                let name = words[1];
                if !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) || name.starts_with('.') {
                    return Err(fail(format!("screenshot name {name:?} may hold only letters, digits, - _ .")));
                }
                steps.push(ScriptStep::Screenshot(name.to_owned()));
            }
            "wait_ms" => {
                expect_args(1)?;
                steps.push(ScriptStep::Wait(Duration::from_millis(count(words.get(1), "milliseconds")?)));
            }
            "quit" => {
                expect_args(0)?;
                steps.push(ScriptStep::Quit);
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
        assert!(err("screenshot ../x").contains("letters"));
        assert!(err("key sideways W").contains("down or up"));
        assert!(err("mouse 1").contains("takes 2 argument"));
    }
}
