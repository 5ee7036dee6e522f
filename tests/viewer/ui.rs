//! The viewer's UI handlers under Xvfb with validation on: the script's commands go through the
//! handler the UI's controls use, and change the image as the keys do; `open` (what a file
//! dropped on the window does) switches scenes, and a bad file keeps the scene shown.

use std::path::Path;

use crate::viewer::{scene_dir, view};

fn rgb(path: &Path) -> image::RgbImage {
    image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8()
}

/// The largest difference of one channel between two images of one size.
fn max_diff(a: &image::RgbImage, b: &image::RgbImage) -> u8 {
    assert_eq!(a.dimensions(), b.dimensions());
    a.pixels().zip(b.pixels()).flat_map(|(p, q)| (0..3).map(move |c| p.0[c].abs_diff(q.0[c]))).max().unwrap_or(0)
}

#[test]
fn commands_change_the_image_as_the_keys_do() {
    let dir = scene_dir("ui-commands");
    // With the UI hidden, so the captures are the frame itself.
    let script = "press F1\nframes 2\ncapture shaded\npress V\nframes 2\ncapture albedo_key\nview shaded\nframes 2\n\
                  capture shaded_again\nview albedo\nframes 2\ncapture albedo_command\nview shaded\n\
                  press +\npress +\nframes 2\ncapture brighter_key\nexposure 0\nframes 2\nexposure 1\nframes 2\n\
                  capture brighter_command\nexposure 0\nlight 0 intensity 0 0 0\nframes 2\ncapture no_sun\n\
                  light 0 intensity 1.6 1.5 1.35\nframes 2\ncapture sun_back\nbookmark save 1\nmouse 200 0\nframes 4\n\
                  capture turned\nbookmark 1\nframes 4\ncapture bookmarked\nquit\n";
    view(&dir, script, &["--hard"]);
    let shaded = rgb(&dir.join("shaded.png"));
    assert!(max_diff(&shaded, &rgb(&dir.join("shaded_again.png"))) <= 1, "`view shaded` is the shaded frame");
    let albedo = rgb(&dir.join("albedo_key.png"));
    assert!(max_diff(&shaded, &albedo) > 40, "V shows another view");
    assert!(max_diff(&albedo, &rgb(&dir.join("albedo_command.png"))) <= 1, "`view albedo` is what V shows");
    let brighter = rgb(&dir.join("brighter_key.png"));
    assert!(max_diff(&shaded, &brighter) > 20, "+ + brightens by 1 EV");
    assert!(max_diff(&brighter, &rgb(&dir.join("brighter_command.png"))) <= 1, "`exposure 1` is what + + does");
    // The sun switched off and on again through the light handler.
    let no_sun = rgb(&dir.join("no_sun.png"));
    assert!(max_diff(&shaded, &no_sun) > 40, "a sun of intensity 0 changes the frame");
    assert!(max_diff(&shaded, &rgb(&dir.join("sun_back.png"))) <= 1, "the sun's intensity restored");
    // A bookmark brings the camera back where it was saved.
    assert!(max_diff(&shaded, &rgb(&dir.join("turned.png"))) > 40, "the camera turned");
    assert!(max_diff(&shaded, &rgb(&dir.join("bookmarked.png"))) <= 1, "bookmark 1 restores the pose");
}

#[test]
fn open_switches_scenes_and_a_bad_file_keeps_the_one_shown() {
    let dir = scene_dir("ui-open");
    // A model (a box above the ground the model path adds, fitted camera and lights) and a
    // scene file of a red floor under a sun, both generated here.
    let mut obj = String::new();
    for z in [0.0, 1.0] {
        for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            obj += &format!("v {x} {} {z}\n", y + 0.5);
        }
    }
    obj += "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 2 3 7 6\nf 4 1 5 8\n";
    std::fs::write(dir.join("box.obj"), obj).unwrap();
    std::fs::write(
        dir.join("red.toml"),
        "[camera]\neye = [0.0, 2.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n\n\
         [[lights]]\ntype = \"directional\"\ndirection = [0.3, -1.0, 0.2]\nirradiance = [2.0, 2.0, 2.0]\n\n\
         [[objects]]\nshape = \"plane\"\nsize = 20.0\nmaterial = { base_color = [0.8, 0.05, 0.05], roughness = 0.8, metallic = 0.0 }\n",
    )
    .unwrap();
    std::fs::write(dir.join("bad.obj"), "v 1 2\nf 1 2 banana\n").unwrap();
    let p = |name: &str| dir.join(name).display().to_string();
    let script = format!(
        "press F1\nframes 2\ncapture before\nopen {}\nframes 2\ncapture kept\nopen {}\nframes 4\ncapture box\n\
         open {}\nframes 4\ncapture red\npress T\nframes 2\nquit\n",
        p("bad.obj"),
        p("box.obj"),
        p("red.toml")
    );
    let out = view(&dir, &script, &["--hard"]);
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    let errors: Vec<&str> = text.lines().filter(|l| l.contains("open ") && l.contains("bad.obj")).collect();
    assert_eq!(errors.len(), 1, "one line for the bad file:\n{text}");
    assert!(errors[0].contains("the scene shown stays"), "{}", errors[0]);
    let before = rgb(&dir.join("before.png"));
    assert!(max_diff(&before, &rgb(&dir.join("kept.png"))) <= 1, "a bad file keeps the scene");
    let boxed = rgb(&dir.join("box.png"));
    assert!(max_diff(&before, &boxed) > 40, "the model replaced the scene");
    // The red floor fills most of the frame.
    let red = rgb(&dir.join("red.png"));
    let reddish = red.pixels().filter(|p| p.0[0] > 2 * p.0[1].max(p.0[2]) + 20).count();
    assert!(reddish * 2 > (red.width() * red.height()) as usize, "only {reddish} red pixels");
}
