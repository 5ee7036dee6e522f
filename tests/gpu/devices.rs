//! `umbra devices` and `--device`: the listing names each device with its index, driver and
//! optional features, and `--device` selects by index or by part of a name.

use crate::common;

#[test]
fn devices_lists_lavapipe_with_its_features() {
    let out = common::umbra().arg("devices").output().expect("run umbra devices");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    let first = text.lines().next().expect("a device");
    assert!(
        first.starts_with("0: llvmpipe") && first.contains("(CPU)") && first.contains("driver llvmpipe Mesa"),
        "{text}"
    );
    let features = text.lines().nth(1).expect("features line");
    for f in ["ray query: ", "geometry shaders: yes", "depth clamp: yes", "timestamps: yes"] {
        assert!(features.contains(f), "{f:?} missing from {features:?}");
    }
    // The listing agrees with what a context on the same device detects.
    let ctx = common::gpu();
    let rq = if ctx.capabilities.ray_query { "ray query: yes" } else { "ray query: no" };
    assert!(features.contains(rq), "{features}");
}

#[test]
fn device_takes_an_index_or_a_name_and_refuses_others() {
    let dir = std::env::temp_dir().join(format!("umbra-devices-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for pick in ["0", "llvm", "LLVMPIPE"] {
        let out = dir.join(format!("pick-{pick}.png"));
        let run =
            common::umbra().args(["render", "--size", "16x16", "--device", pick, "-o"]).arg(&out).output().unwrap();
        assert!(run.status.success(), "--device {pick}: {}", String::from_utf8_lossy(&run.stderr));
        assert!(out.is_file());
    }
    for bad in ["7", "no-such-gpu"] {
        let out = dir.join("bad.png");
        let run =
            common::umbra().args(["render", "--size", "16x16", "--device", bad, "-o"]).arg(&out).output().unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success() && !out.exists(), "--device {bad} should fail");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(&format!("--device \"{bad}\"")) && err.contains("0: llvmpipe"), "{err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A driver manifest that is not JSON (`VK_ICD_FILENAMES` naming `{not json`) loads no driver;
/// the loader reports that as a failed host allocation, which umbra passed on ("A host memory
/// allocation has failed"). Now the one error line says no driver could be loaded and names
/// the variables that chose the drivers, for `devices` and for a render alike.
#[test]
fn a_driver_manifest_that_is_not_json_is_named_as_no_driver() {
    let dir = tempfile::tempdir().unwrap();
    let icd = dir.path().join("broken_icd.json");
    std::fs::write(&icd, "{not json").unwrap();
    let png = dir.path().join("a.png");
    for args in [vec!["devices"], vec!["render", "--size", "16x16", "-o", png.to_str().unwrap()]] {
        let run = common::umbra()
            .args(&args)
            .env("VK_ICD_FILENAMES", &icd)
            .env("VK_DRIVER_FILES", &icd)
            .output()
            .expect("run umbra");
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {err}");
        let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{args:?}: {err}");
        let line = errors[0];
        assert!(line.contains("no Vulkan driver could be loaded"), "{args:?}: {line}");
        let named = format!("VK_ICD_FILENAMES=\"{0}\" and VK_DRIVER_FILES=\"{0}\" choose the drivers", icd.display());
        assert!(line.contains(&named), "{args:?}: {named:?} not in {line}");
        assert!(!line.contains("host memory"), "{args:?}: {line}");
        assert!(!png.exists());
    }
}
