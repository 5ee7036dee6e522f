//! `umbra render --sequence`: the instants of a moving scene to render, which of them this
//! process renders (`--shard K/N`, or a Slurm array or Kubernetes Indexed Job's index), and the
//! numbered file each goes to.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

/// The frames of a sequence: from `start` at `fps`, `count` of them (frame i at
/// `start + i / fps`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Frames {
    pub start: f64,
    pub fps: f64,
    pub count: usize,
}

impl Frames {
    /// The frames of `[start, end)` at `fps`: `start`, `start + 1/fps`, ... before `end` (a span
    /// shorter than one frame still has its first).
    pub fn new(start: f64, end: f64, fps: f64) -> Frames {
        // Rounding guard: a span of exactly n frames gives n, not n + 1.
        let count = (((end - start) * fps) - 1e-9).ceil().max(1.0) as usize;
        Frames { start, fps, count }
    }

    /// Frame `i`'s instant, in seconds.
    pub fn time(&self, i: usize) -> f64 {
        self.start + i as f64 / self.fps
    }
}

/// `--shard K/N`: part K (from 1) of N.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// The whole job, unsplit.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Whether item `i` of a job (a sequence's frame, a bench grid's point) is this shard's:
    /// items are dealt round-robin, so shards get runs of the job's length / N items each,
    /// balanced wherever the expensive items lie.
    pub fn owns(&self, i: usize) -> bool {
        i % self.count == self.index - 1
    }
}

/// Parses `K/N` (1 <= K <= N).
pub(crate) fn parse_shard(text: &str) -> Result<Shard, String> {
    let bad = || format!("{text:?}: write K/N, this process's part K of N parts, 1 <= K <= N (e.g. 2/8)");
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let (index, count) = (k.trim().parse::<usize>().map_err(|_| bad())?, n.trim().parse::<usize>().map_err(|_| bad())?);
    if index == 0 || count == 0 || index > count {
        return Err(bad());
    }
    Ok(Shard { index, count })
}

/// The shard this process renders: `--shard` where given; else a Slurm job array's task
/// (`SLURM_ARRAY_TASK_ID` from `SLURM_ARRAY_TASK_MIN`, of `SLURM_ARRAY_TASK_COUNT`); else a
/// Kubernetes Indexed Job's `JOB_COMPLETION_INDEX` (from 0), of `--shards`; else all of it.
pub(crate) fn resolve_shard(
    given: Option<Shard>,
    shards: Option<usize>,
    env: impl Fn(&str) -> Option<String>,
) -> Result<Shard> {
    if let Some(shard) = given {
        return Ok(shard);
    }
    let number = |name: &str| -> Result<Option<usize>> {
        match env(name) {
            None => Ok(None),
            Some(v) => match v.trim().parse::<usize>() {
                Ok(n) => Ok(Some(n)),
                Err(_) => bail!("{name}={v:?}: not a whole number"),
            },
        }
    };
    if let (Some(id), Some(count)) = (number("SLURM_ARRAY_TASK_ID")?, number("SLURM_ARRAY_TASK_COUNT")?) {
        let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
        let Some(index) = id.checked_sub(min).filter(|&i| i < count) else {
            bail!("SLURM_ARRAY_TASK_ID={id} lies outside the array's {count} tasks from SLURM_ARRAY_TASK_MIN={min}")
        };
        if shards.is_some_and(|n| n != count) {
            bail!("--shards {} contradicts SLURM_ARRAY_TASK_COUNT={count}", shards.unwrap_or_default());
        }
        return Ok(Shard { index: index + 1, count });
    }
    if let Some(index) = number("JOB_COMPLETION_INDEX")? {
        let Some(count) = shards else {
            bail!("JOB_COMPLETION_INDEX={index} is set: give the Job's completions as --shards N")
        };
        if index >= count {
            bail!("JOB_COMPLETION_INDEX={index} is not below --shards {count}");
        }
        return Ok(Shard { index: index + 1, count });
    }
    if let Some(count) = shards {
        bail!("--shards {count}: no shard index (--shard K/N, a Slurm array task or JOB_COMPLETION_INDEX)");
    }
    Ok(Shard::ALL)
}

/// Frame `number`'s file: `pattern` with its run of `#` replaced by the number, zero-padded to
/// the run's length (`frames/shot_####.png`), or, without `#`, with `_NNNN` before the extension
/// (`shot.png` -> `shot_0001.png`).
pub(crate) fn numbered(pattern: &Path, number: usize) -> Result<PathBuf> {
    let name = pattern.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let hashes = name.matches('#').count();
    let file = if hashes == 0 {
        let stem = pattern.file_stem().and_then(|s| s.to_str()).unwrap_or("frame");
        match pattern.extension().and_then(|e| e.to_str()) {
            Some(ext) => format!("{stem}_{number:04}.{ext}"),
            None => format!("{stem}_{number:04}"),
        }
    } else {
        let first = name.find('#').unwrap_or_default();
        let run = &name[first..first + hashes];
        if run.chars().any(|c| c != '#') {
            bail!("{}: put the frame number's #s together (one run, e.g. shot_####.png)", pattern.display());
        }
        format!("{}{number:0hashes$}{}", &name[..first], &name[first + hashes..])
    };
    Ok(pattern.with_file_name(file))
}

/// A progress bar over `images` (a sequence's, or one) of `frames` frames each, on stderr when it
/// is a terminal and the log shows warnings or more (hidden otherwise, and under -q); its
/// message follows the frame count (one image's samples per pixel).
pub(crate) fn progress(images: usize, frames: u32) -> indicatif::ProgressBar {
    let total = images as u64 * u64::from(frames);
    if !std::io::IsTerminal::is_terminal(&std::io::stderr()) || !log::log_enabled!(log::Level::Warn) {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(total);
    let style = indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} frames{msg}, {elapsed} ({eta} left)")
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
    bar.set_style(style);
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_cover_the_span_at_the_rate() {
        let f = Frames::new(0.0, 2.0, 24.0);
        assert_eq!(f.count, 48);
        assert_eq!(f.time(24), 1.0);
        assert_eq!(Frames::new(1.0, 1.01, 24.0).count, 1);
        assert_eq!(Frames::new(0.0, 0.1, 30.0).count, 3);
    }

    #[test]
    fn shards_deal_frames_round_robin_into_disjoint_parts() {
        let shards: Vec<Shard> = (1..=3).map(|k| Shard { index: k, count: 3 }).collect();
        for i in 0..100 {
            assert_eq!(shards.iter().filter(|s| s.owns(i)).count(), 1, "frame {i}");
        }
        assert_eq!(parse_shard("2/8"), Ok(Shard { index: 2, count: 8 }));
        for bad in ["0/3", "4/3", "1", "a/b", "1/0"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_environment_names_the_shard_where_no_flag_does() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| pairs.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
        };
        let slurm =
            env(&[("SLURM_ARRAY_TASK_ID", "5"), ("SLURM_ARRAY_TASK_MIN", "4"), ("SLURM_ARRAY_TASK_COUNT", "3")]);
        assert_eq!(resolve_shard(None, None, slurm).unwrap(), Shard { index: 2, count: 3 });
        let k8s = env(&[("JOB_COMPLETION_INDEX", "0")]);
        assert_eq!(resolve_shard(None, Some(4), k8s).unwrap(), Shard { index: 1, count: 4 });
        assert!(resolve_shard(None, None, env(&[("JOB_COMPLETION_INDEX", "0")])).is_err());
        assert_eq!(resolve_shard(Some(Shard { index: 3, count: 3 }), None, k8s).unwrap().index, 3);
        assert_eq!(resolve_shard(None, None, env(&[])).unwrap(), Shard::ALL);
    }

    #[test]
    fn frame_files_are_numbered_where_the_pattern_says() {
        assert_eq!(numbered(Path::new("frames/shot_####.png"), 7).unwrap(), PathBuf::from("frames/shot_0007.png"));
        assert_eq!(numbered(Path::new("shot.exr"), 12).unwrap(), PathBuf::from("shot_0012.exr"));
        assert_eq!(numbered(Path::new("a##b.png"), 3).unwrap(), PathBuf::from("a03b.png"));
        assert!(numbered(Path::new("a#b#.png"), 3).is_err());
    }
}
