//! A short soak of the viewer: 1,000 frames at 160x120 with hard shadows under Xvfb, the camera
//! moving, the window resized and the views toggled every few frames, resident memory sampled
//! every 50 ms. Validation is off: the layers' own bookkeeping grows with every call, and that
//! is not ours. After a warm-up (the first third of the samples: pipelines, caches and both
//! window sizes made), resident memory may grow by at most `MAX_GROWTH_MIB`.
//! `tools/soak` runs the long version (UMBRA_SOAK_FRAMES=10000, which also cycles the shadow
//! methods with T: hard, soft, none, map) and reports the same figures.

use crate::common;

use std::time::{Duration, Instant};

/// Resident memory may grow this much after warm-up (MiB): 0.4 MiB was measured over 1,000
/// frames; a leak of 6 KiB a frame would pass 4 MiB over the ~650 frames after warm-up.
const MAX_GROWTH_MIB: f64 = 4.0;

/// The script: moves, resizes and view toggles (and with `methods`, a shadow method change
/// every block), repeated to `frames`.
fn soak_script(frames: u64, methods: bool) -> String {
    let block = "key down W\nframes 5\nkey up W\nmouse 30 0\nframes 5\nresize 200 150\nframes 5\npress V\nframes 5\n\
                 press V\npress V\npress V\npress V\npress V\npress V\nresize 160 120\nkey down S\nframes 5\nkey up S\n\
                 mouse -30 0\nframes 5\n";
    let per_block = 30;
    let mut script = String::new();
    for _ in 0..frames.div_ceil(per_block) + 1 {
        script += block;
        if methods {
            script += "press T\n";
        }
    }
    script
}

fn rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[test]
fn resident_memory_stays_flat_over_1000_frames() {
    let frames: u64 = std::env::var("UMBRA_SOAK_FRAMES").ok().and_then(|v| v.parse().ok()).unwrap_or(1000);
    common::lavapipe_env();
    let dir = std::env::temp_dir().join(format!("umbra-soak-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("script.txt"), soak_script(frames, frames > 1000)).unwrap();
    let pid_file = dir.join("pid");
    // The shell records the viewer's own pid (xvfb-run's child would be the shell).
    let command = format!(
        "{} view --hard --size 160x120 --frames {frames} --fixed-dt 0.0166667 --script {} & echo $! > {}; wait $!",
        env!("CARGO_BIN_EXE_umbra"),
        dir.join("script.txt").display(),
        pid_file.display()
    );
    let _one_at_a_time = common::XVFB.lock().unwrap_or_else(|e| e.into_inner());
    let child = std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 640x480x24", "sh", "-c", &command])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("xvfb-run (installed by tools/setup)");
    let start = Instant::now();
    let pid = loop {
        if let Some(pid) = std::fs::read_to_string(&pid_file).ok().and_then(|t| t.trim().parse::<u32>().ok()) {
            break pid;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "the viewer did not start");
        std::thread::sleep(Duration::from_millis(10));
    };
    let mut samples = Vec::new();
    while let Some(kib) = rss_kib(pid) {
        samples.push(kib);
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success() && text.contains(&format!("viewer: {frames} frames presented")), "{text}");
    assert!(samples.len() >= 12, "only {} memory samples: {text}", samples.len());
    let warm = samples.len() / 3;
    let after_warm_up = samples[warm];
    let peak = *samples[warm..].iter().max().unwrap();
    let last = *samples.last().unwrap();
    let growth_mib = (peak.max(last) as f64 - after_warm_up as f64) / 1024.0;
    println!(
        "soak: {frames} frames in {:.1} s, {} samples; resident {:.1} MiB after warm-up, peak {:.1}, last {:.1}: \
         growth {growth_mib:.2} MiB (bound {MAX_GROWTH_MIB})",
        start.elapsed().as_secs_f64(),
        samples.len(),
        after_warm_up as f64 / 1024.0,
        peak as f64 / 1024.0,
        last as f64 / 1024.0
    );
    assert!(growth_mib <= MAX_GROWTH_MIB, "resident memory grew {growth_mib:.2} MiB after warm-up");
    let _ = std::fs::remove_dir_all(&dir);
}
