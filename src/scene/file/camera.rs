//! The scene's camera: a `[camera]` table, or one a glTF `scene` places.

use super::desc::CameraChoice;
use super::{gltf, shorten, Camera, Check, SceneError, MAX_MESSAGE_CHARS};

impl Check<'_> {
    /// `[camera]` wins; `camera = N` picks camera N of the glTF `scene`; without either, that
    /// scene's first camera.
    pub(super) fn camera_choice(
        &self,
        choice: Option<&CameraChoice>,
        whole: Option<(&str, &gltf::LoadedGltf)>,
    ) -> Result<Camera, SceneError> {
        let cameras = whole.map(|(name, g)| (shorten(name, MAX_MESSAGE_CHARS), &g.cameras));
        match (choice, cameras) {
            (Some(CameraChoice::Table(camera)), _) => self.camera(camera),
            (Some(CameraChoice::Index(n)), Some((name, cameras))) => {
                let found = usize::try_from(*n).ok().and_then(|n| cameras.get(n)).copied().flatten();
                found.ok_or_else(|| {
                    let placed = cameras.iter().filter(|c| c.is_some()).count();
                    let message = format!(
                        "{name:?} has no perspective camera {n} placed by a node (it has {} cameras, {placed} usable)",
                        cameras.len()
                    );
                    self.fail("camera", message)
                })
            }
            (Some(CameraChoice::Index(_)), None) => {
                Err(self
                    .fail("camera", "a camera index picks a camera of `scene`; without `scene` give a [camera] table"))
            }
            (None, Some((name, cameras))) => cameras.iter().flatten().next().copied().ok_or_else(|| {
                self.fail("camera", format!("missing [camera] table, and {name:?} places no perspective camera"))
            }),
            (None, None) => Err(self.fail("camera", "missing [camera] table; every scene needs one")),
        }
    }
}

/// Which of the glTF `scene`'s cameras `camera_choice` took, if it took one.
pub(super) fn whole_camera_index(choice: Option<&CameraChoice>, cameras: &[Option<Camera>]) -> Option<usize> {
    match choice {
        Some(CameraChoice::Table(_)) => None,
        Some(CameraChoice::Index(n)) => usize::try_from(*n).ok(),
        None => cameras.iter().position(Option::is_some),
    }
}
