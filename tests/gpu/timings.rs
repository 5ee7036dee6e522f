//! `--timings` tells the truth: a compute pass of known cost ("busy", added by a hidden flag
//! right after the geometry pass, the case where Mesa 25's lavapipe defers timestamps) is timed
//! as long as it makes the frame take by the host clock, and the GPU frame time matches the
//! host's when that pass dominates. Run as the binary, on one lavapipe thread, so the
//! busy pass's single workgroup is not hidden behind other threads' work.

use crate::common;

use common::umbra;

/// Loop iterations of the busy pass: the most it takes (about 35 ms on a 2-core test machine),
/// far more than the rest of a 64x48 frame of the default scene.
const BUSY: &str = "65535";
const FRAMES: &str = "16";

/// Stdout and stderr (the calibration's log line) of a timed render of the default scene.
fn render(busy: bool) -> String {
    let dir = common::scratch_dir("timings");
    let out = dir.join(if busy { "busy.png" } else { "plain.png" });
    let mut args = vec!["render", "-o", out.to_str().unwrap(), "--size", "64x48", "--frames", FRAMES];
    args.extend(["--timings", "--validate"]);
    if busy {
        args.extend(["--busy-pass", BUSY]);
    }
    let o = umbra().args(&args).env("LP_NUM_THREADS", "1").env("RUST_LOG", "umbra=info").output().expect("run umbra");
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}{err}");
    assert!(text.contains("validation: 0 messages"), "{text}");
    assert!(text.contains("GPU time per pass ("), "timings unavailable?\n{text}{err}");
    format!("{text}{err}")
}

/// The median of the row named `name` ("  NAME   1.234 ms   IQR  0.123 ms ...").
fn median(text: &str, name: &str) -> Option<f64> {
    text.lines().filter(|l| l.starts_with("  ")).find_map(|line| {
        let words: Vec<&str> = line.split_whitespace().collect();
        let at =
            (0..words.len().saturating_sub(1)).find(|&i| words[i].parse::<f64>().is_ok() && words[i + 1] == "ms")?;
        (words[..at].join(" ") == name).then(|| words[at].parse().unwrap())
    })
}

fn within_factor_2(a: f64, b: f64) -> bool {
    a > 0.0 && b > 0.0 && a <= 2.0 * b && b <= 2.0 * a
}

#[test]
fn busy_pass_is_timed_as_long_as_the_host_clock_says() {
    let plain = render(false);
    let busy = render(true);
    let report = format!("without the busy pass:\n{plain}\nwith it:\n{busy}");
    let get = |text: &str, name: &str| median(text, name).unwrap_or_else(|| panic!("no {name:?} row\n{report}"));
    assert!(median(&plain, "busy").is_none(), "{report}");
    let host_without = get(&plain, "host per frame");
    let host_with = get(&busy, "host per frame");
    let busy_ms = get(&busy, "busy");
    let gpu_frame = get(&busy, "GPU frame");
    let added = host_with - host_without;
    // The premise: the busy pass dominates the frame it is added to.
    assert!(added > 0.5 * host_with, "the busy pass adds {added:.3} ms to {host_with:.3} ms frames\n{report}");
    assert!(
        within_factor_2(busy_ms, added),
        "busy pass timed {busy_ms:.3} ms, but it adds {added:.3} ms per frame by the host clock\n{report}"
    );
    assert!(
        within_factor_2(gpu_frame, host_with),
        "GPU frame {gpu_frame:.3} ms, host {host_with:.3} ms per frame\n{report}"
    );
    println!("{report}");
}
