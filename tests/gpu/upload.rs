//! Scene uploads: on a device whose memory is the host's (lavapipe) buffers are written in place,
//! elsewhere through staging buffers and a copy pass. Both paths give the same bytes; the staged
//! one is exercised here because the test device itself takes the other.

use crate::common;

use ash::vk;
use umbra::gpu::{unified_memory, upload, upload_staged};

#[test]
fn in_place_and_staged_uploads_hold_the_same_bytes() {
    let ctx = common::gpu();
    assert!(unified_memory(&ctx), "lavapipe is a CPU device: uploads write in place");
    let a: Vec<u8> = (0..100_003u32).map(|i| (i.wrapping_mul(2654435761) >> 24) as u8).collect();
    let b: Vec<u8> = (0..4096u32).flat_map(|i| i.to_le_bytes()).collect();
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let items = || [("a", a.as_slice(), usage), ("b", b.as_slice(), usage), ("empty", &[][..], usage)];
    let direct = upload(&ctx, items()).expect("upload");
    let staged = upload_staged(&ctx, items()).expect("staged upload");
    for (buffers, how) in [(&direct, "in place"), (&staged, "staged")] {
        // lavapipe's device-local memory is host-visible too, so the staged copies can be read.
        assert_eq!(&buffers[0].mapped()[..a.len()], a.as_slice(), "{how}");
        assert_eq!(&buffers[1].mapped()[..b.len()], b.as_slice(), "{how}");
    }
    drop((direct, staged));
    common::assert_clean(&ctx);
}
