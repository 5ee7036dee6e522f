//! Shared by the GPU tests: a lavapipe context with validation and synchronization validation
//! on, and a check that no message was reported.

#![allow(dead_code)]

use std::sync::{Arc, Once};

use umbra::vk::{GpuContext, GpuOptions};

static ENV: Once = Once::new();

/// Points the loader at lavapipe unless the caller chose a driver already (tools/test does).
pub fn lavapipe_env() {
    ENV.call_once(|| {
        if std::env::var_os("VK_ICD_FILENAMES").is_none() {
            let icd = std::fs::read_dir("/usr/share/vulkan/icd.d")
                .expect("Vulkan ICD directory; run tools/setup")
                .filter_map(|e| e.ok().map(|e| e.path()))
                .find(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("lvp_icd")))
                .expect("lavapipe ICD; run tools/setup");
            std::env::set_var("VK_ICD_FILENAMES", &icd);
            std::env::set_var("VK_DRIVER_FILES", &icd);
        }
        if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
            let dir = std::env::temp_dir().join("umbra-test-xdg");
            std::fs::create_dir_all(&dir).expect("runtime dir");
            std::env::set_var("XDG_RUNTIME_DIR", dir);
        }
    });
}

/// A validated lavapipe context. Every GPU test ends with `assert_clean`.
pub fn gpu() -> Arc<GpuContext> {
    lavapipe_env();
    let ctx = GpuContext::new(&GpuOptions { validate: true, device_name: Some("llvmpipe".into()) })
        .expect("lavapipe with validation; run tools/setup");
    assert!(ctx.validation_enabled());
    ctx
}

pub fn assert_clean(ctx: &GpuContext) {
    let messages = ctx.validation_log().messages();
    assert!(messages.is_empty(), "{} validation message(s):\n{}", messages.len(), messages.join("\n---\n"));
}

/// The built binary, with lavapipe selected.
pub fn umbra() -> std::process::Command {
    lavapipe_env();
    std::process::Command::new(env!("CARGO_BIN_EXE_umbra"))
}
