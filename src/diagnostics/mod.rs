//! What measures the renderer from outside its frames: the timestamp calibration and the busy
//! pass it times, and the ray batch that traces a given list of rays (the BVH's GPU tests and
//! `umbra bench rays`).

pub mod busy;
pub mod calibration;
pub mod ray_batch;

/// The process's resident memory now and at its peak, in bytes (Linux's `VmRSS` and `VmHWM`);
/// `None` where the system does not say.
pub fn resident_memory() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kib: u64 = line[name.len()..].trim().trim_end_matches("kB").trim().parse().ok()?;
        Some(kib << 10)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}
