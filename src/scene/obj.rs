//! OBJ/MTL loading through tobj, to object-space meshes with their MTL materials mapped onto the
//! renderer's metalness/roughness model. Files are read here, not by tobj, so errors keep the
//! io reason and the line they happened on.

use std::cell::RefCell;
use std::io::{self, BufRead, Read};
use std::path::{Path, PathBuf};

use std::sync::Arc;

use glam::{DVec3, Vec2, Vec3};

use super::input;
use super::mesh::{ObjectMesh, ObjectSurface};
use super::texture::{ChannelMap, MaterialTextures, TextureCache};
use super::{tangents, Material};

/// Why an OBJ file could not be used.
#[derive(Debug)]
pub(super) enum ObjError {
    Read(io::Error),
    Parse(String),
}

/// An OBJ file as loaded: one mesh per model, what was dropped on the way, and the MTL files it
/// named.
pub(super) struct LoadedObj {
    pub meshes: Vec<ObjectMesh>,
    /// `f` lines with one or two corners: points and lines, which tobj leaves out.
    pub short_faces: usize,
    /// Every material library the file names, as looked up (read or not).
    pub material_files: Vec<PathBuf>,
}

/// Loads every model of the OBJ file at `path` (one `ObjectMesh` per model), with the materials
/// of its MTL libraries looked up next to it. A missing or broken MTL only costs the materials.
pub(super) fn load(path: &Path, textures: &mut TextureCache) -> Result<LoadedObj, ObjError> {
    let bytes = input::read(path).map_err(ObjError::Read)?;
    check_is_obj(&bytes).map_err(ObjError::Parse)?;
    check_indices(&bytes).map_err(ObjError::Parse)?;
    let short_faces = count_short_faces(&bytes);
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let dir = path.parent().unwrap_or(Path::new(""));
    let material_files = RefCell::new(Vec::new());
    // The directory of each library read and how many materials it gave: tobj appends them in
    // the order the libraries are named.
    let libraries = RefCell::new(Vec::new());
    let mut reader = LineCounter::new(&bytes);
    let loaded = tobj::load_obj_buf(&mut reader, &options, |mtl| {
        let mtl = dir.join(mtl);
        material_files.borrow_mut().push(mtl.clone());
        let result = load_mtl(path, &mtl);
        if let Ok((materials, _)) = &result {
            libraries.borrow_mut().push((mtl.parent().unwrap_or(dir).to_path_buf(), materials.len()));
        }
        result
    });
    let (models, materials) = loaded.map_err(|e| ObjError::Parse(located(e, reader.lines)))?;
    // Every library that failed was named in `load_mtl`'s warning already, once.
    let materials = materials.unwrap_or_default();

    let file_name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    // Texture paths are relative to the material library that names them.
    let texture_dirs: Vec<PathBuf> =
        libraries.into_inner().into_iter().flat_map(|(dir, count)| std::iter::repeat_n(dir, count)).collect();
    let material_textures: Vec<Option<Arc<MaterialTextures>>> = materials
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let label = format!("{file_name}: material {:?}", m.name);
            let texture_dir = texture_dirs.get(k).map_or(dir, PathBuf::as_path);
            let maps = texture_maps(m, texture_dir, textures, &label);
            (!maps.is_empty()).then(|| Arc::new(maps))
        })
        .collect();
    let meshes = models
        .into_iter()
        .map(|model| {
            let mesh = model.mesh;
            let positions = to_dvec3(&mesh.positions);
            // tobj leaves normals short when only some faces have `vn`; shade such a mesh flat.
            let normals = Some(to_vec3(&mesh.normals)).filter(|n| n.len() == positions.len());
            let mtl = mesh.material_id.and_then(|id| materials.get(id));
            let textures = mesh.material_id.and_then(|id| material_textures.get(id).cloned().flatten());
            // OBJ's v runs up from the image's bottom; umbra samples with glTF's (from the top).
            let uvs: Vec<Vec2> = mesh.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], 1.0 - t[1])).collect();
            // Emission from Ke alone reads no texel: zero coordinates do where the file has none.
            let constant_only = textures.as_ref().is_some_and(|t| {
                t.base_color.is_none()
                    && t.roughness.is_none()
                    && t.metallic.is_none()
                    && t.normal.is_none()
                    && t.emission_map.is_none()
            });
            let uvs =
                if uvs.len() != positions.len() && constant_only { vec![Vec2::ZERO; positions.len()] } else { uvs };
            let surface = match textures {
                Some(textures) if uvs.len() == positions.len() => {
                    ObjectSurface { uvs: Some(uvs), uvs_1: None, tangents: None, textures: Some(textures) }
                }
                _ => ObjectSurface::default(),
            };
            let mut object_mesh = ObjectMesh {
                name: format!("{file_name}/{}", model.name),
                positions,
                normals,
                indices: mesh.indices,
                material: mtl.map(|m| textured_constants(convert_material(m), surface.textures.as_deref())),
                surface,
                double_sided: false,
            };
            let normal_map = object_mesh.surface.textures.as_ref().is_some_and(|t| t.normal.is_some());
            if normal_map && !tangents::generate(&mut object_mesh) {
                log::warn!(
                    "{}: no tangent frame for its normal map (degenerate texture coordinates?)",
                    object_mesh.name
                );
            }
            object_mesh
        })
        .collect();
    Ok(LoadedObj { meshes, short_faces, material_files: material_files.into_inner() })
}

/// Statements that make a file an OBJ file; tobj skips any other line without a word, so a text
/// file (or a renamed PNG) named `.obj` would otherwise load as an empty mesh.
const OBJ_KEYWORDS: &[&str] =
    &["v", "vt", "vn", "vp", "f", "l", "p", "o", "g", "s", "usemtl", "mtllib", "cstype", "curv", "surf"];

/// The file's text for the checks below, which read it as tobj does: a line ends at '\n' and
/// splits into words by `str::split_whitespace` (Unicode white space, so a no-break space
/// separates words too). Bytes that are not UTF-8 are replaced here; tobj refuses their line.
fn obj_text(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(bytes)
}

/// Refuses content that is not OBJ text: binary data (a NUL byte), or lines none of which is an
/// OBJ statement. A file of comments and blank lines only is an empty OBJ, not a wrong one.
fn check_is_obj(bytes: &[u8]) -> Result<(), String> {
    if bytes.contains(&0) {
        return Err("binary data (a NUL byte), not OBJ text".to_owned());
    }
    let mut content = None;
    for (n, line) in obj_text(bytes).split('\n').enumerate() {
        let Some(first) = line.split_whitespace().next() else { continue };
        if first.starts_with('#') {
            continue;
        }
        if OBJ_KEYWORDS.contains(&first) {
            return Ok(());
        }
        content.get_or_insert(n + 1);
    }
    match content {
        Some(line) => Err(format!("line {line}: no OBJ statement (v, f, o, ...) anywhere in the file")),
        None => Ok(()),
    }
}

/// Refuses a face corner whose index names no vertex, texture coordinate or normal: a positive
/// index past the file's count of them, or a negative (relative) one reaching back past the
/// first. tobj turns such a relative index into a huge one and overflows its arithmetic on it
/// (a panic where overflow is checked; found by `tools/fuzz --afl`), so they are caught here,
/// with the line.
fn check_indices(bytes: &[u8]) -> Result<(), String> {
    let text = obj_text(bytes);
    let lines = || text.split('\n');
    const KINDS: [(&str, &str); 3] = [("v", "vertex"), ("vt", "texture coordinate"), ("vn", "normal")];
    let mut total = [0i64; 3];
    for line in lines() {
        if let Some(k) = line.split_whitespace().next().and_then(|w| KINDS.iter().position(|(key, _)| *key == w)) {
            total[k] += 1;
        }
    }
    let mut seen = [0i64; 3];
    for (n, line) in lines().enumerate() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let Some(&first) = words.first() else { continue };
        if let Some(k) = KINDS.iter().position(|(key, _)| *key == first) {
            seen[k] += 1;
            continue;
        }
        if !matches!(first, "f" | "l" | "p") {
            continue;
        }
        for corner in &words[1..] {
            for (k, part) in corner.split('/').enumerate().take(3) {
                let Ok(index) = part.parse::<i64>() else { continue };
                if k > 0 && total[k] == 0 {
                    continue; // tobj ignores texture and normal indices of a file that has none
                }
                let fits = match index {
                    i if i > 0 => i <= total[k],
                    i if i < 0 => -i <= seen[k],
                    _ => false,
                };
                if !fits {
                    let (_, what) = KINDS[k];
                    let have = if index < 0 { seen[k] } else { total[k] };
                    return Err(format!(
                        "line {}: {first} index {index} names no {what} (there are {have}{})",
                        n + 1,
                        if index < 0 { " before it" } else { "" }
                    ));
                }
            }
        }
    }
    Ok(())
}

/// `f` lines with one or two vertex references, which tobj parses as points and lines and, with
/// `ignore_points` and `ignore_lines`, leaves out without a word.
fn count_short_faces(bytes: &[u8]) -> usize {
    obj_text(bytes)
        .split('\n')
        .filter(|line| {
            let mut words = line.split_whitespace();
            words.next() == Some("f") && matches!(words.count(), 1 | 2)
        })
        .count()
}

fn to_vec3(flat: &[f32]) -> Vec<Vec3> {
    flat.chunks_exact(3).map(Vec3::from_slice).collect()
}

/// OBJ positions as tobj reads them (f32, in object space), widened to the mesh type's f64.
fn to_dvec3(flat: &[f32]) -> Vec<DVec3> {
    flat.chunks_exact(3).map(|p| Vec3::from_slice(p).as_dvec3()).collect()
}

/// Names the line for errors tobj raises while reading one; the rest surface later, when it
/// assembles a model, where the current line would mislead.
fn located(error: tobj::LoadError, lines_read: usize) -> String {
    use tobj::LoadError::*;
    match error {
        PositionParseError
        | NormalParseError
        | TexcoordParseError
        | FaceParseError
        | ColorParseError
        | ScalingByZeroError
        | InvalidObjectName
        | UnrecognizedCharacter
        | ReadError => format!("line {lines_read}: {error}"),
        _ => error.to_string(),
    }
}

/// Reads an MTL library for tobj, refusing the lines tobj would panic on (a colour with fewer
/// than three numbers). A library that cannot be used is one warning, here, naming it (tobj's
/// own error after it says nothing more).
fn load_mtl(obj: &Path, mtl: &Path) -> tobj::MTLLoadResult {
    const COST: &str = "its materials are left out, and faces that use them get the default";
    let bytes = input::read(mtl).map_err(|e| {
        log::warn!("{}: cannot read material library {}: {e}; {COST}", obj.display(), mtl.display());
        tobj::LoadError::OpenFileFailed
    })?;
    let text = String::from_utf8_lossy(&bytes);
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if matches!(words.next(), Some("Ka" | "Kd" | "Ks" | "Ke")) && words.count() < 3 {
            log::warn!("{}:{}: colour needs three numbers; {COST}", mtl.display(), n + 1);
            return Err(tobj::LoadError::MaterialParseError);
        }
    }
    let mut reader = LineCounter::new(text.as_bytes());
    tobj::load_mtl_buf(&mut reader).inspect_err(|e| {
        log::warn!("{}:{}: {e}; {COST}", mtl.display(), reader.lines);
    })
}

/// MTL (Phong) to metalness/roughness. Kd is the base colour; Pr/Pm (the PBR extension) win when
/// given; otherwise roughness comes from the Phong exponent Ns through the usual Beckmann match
/// alpha^2 = 2 / (Ns + 2), with perceptual roughness = sqrt(alpha).
fn convert_material(mtl: &tobj::Material) -> Material {
    let default = Material::default();
    let unit = |value: f32| value.is_finite().then(|| value.clamp(0.0, 1.0));
    let param = |key: &str| mtl.unknown_param.get(key).and_then(|v| v.trim().parse::<f32>().ok());

    let base_color = mtl
        .diffuse
        .map(Vec3::from)
        .filter(|c| c.is_finite())
        .map_or(default.base_color, |c| c.clamp(Vec3::ZERO, Vec3::ONE));
    let from_shininess = |ns: f32| (2.0 / (ns.max(0.0) + 2.0)).powf(0.25);
    let roughness = param("Pr")
        .and_then(unit)
        .or_else(|| mtl.shininess.map(from_shininess).and_then(unit))
        .unwrap_or(default.roughness);
    let metallic = param("Pm").and_then(unit).unwrap_or(default.metallic);
    Material { base_color, roughness, metallic }
}

/// An MTL texture statement's file and its `-bm` scale: tobj keeps the options in front of the
/// file name (`-bm 0.5 -clamp on normal.png`). Options take the arguments the MTL format gives
/// them; the file name is what follows (it may contain spaces).
fn texture_statement(value: &str) -> (String, Option<f32>) {
    let words: Vec<&str> = value.split_whitespace().collect();
    let mut bump = None;
    let mut at = 0;
    while at < words.len() && words[at].starts_with('-') {
        let arguments = match words[at] {
            "-o" | "-s" | "-t" => words[at + 1..].iter().take(3).take_while(|w| w.parse::<f32>().is_ok()).count(),
            "-mm" => 2,
            "-bm" => {
                bump = words.get(at + 1).and_then(|w| w.parse::<f32>().ok());
                1
            }
            _ => 1, // -blendu, -blendv, -clamp, -cc, -imfchan, -texres, -boost, -type
        };
        at += 1 + arguments;
    }
    (words.get(at..).map_or_else(String::new, |rest| rest.join(" ")), bump)
}

/// The texture maps a material names: `map_Kd` (sRGB), `map_Pr` and `map_Pm` (linear, red
/// channel), `map_RMA` (R roughness, G metalness, B occlusion), `Ke`/`map_Ke` emission, and the normal
/// map from `norm`, `map_Kn` or `map_bump`/`bump` with its `-bm` scale (tangent space, OpenGL
/// convention).
fn texture_maps(mtl: &tobj::Material, dir: &Path, cache: &mut TextureCache, label: &str) -> MaterialTextures {
    let param = |key: &str| mtl.unknown_param.get(key).map(String::as_str).filter(|v| !v.trim().is_empty());
    let mut load = |value: Option<&str>, srgb: bool| {
        let (file, bump) = texture_statement(value?);
        if file.is_empty() {
            return None;
        }
        cache.get(&dir.join(&file), &file, srgb, label).map(|t| (t, bump))
    };
    let base_color = load(mtl.diffuse_texture.as_deref(), true).map(|(t, _)| t);
    let rma = load(param("map_RMA"), false).map(|(t, _)| t);
    let roughness = load(param("map_Pr"), false).map(|(texture, _)| ChannelMap { texture, channel: 0 });
    let metallic = load(param("map_Pm"), false).map(|(texture, _)| ChannelMap { texture, channel: 0 });
    let normal_statement = param("norm").or(param("map_Kn")).or(mtl.normal_texture.as_deref());
    let normal = load(normal_statement, false).map(|(t, bump)| (t, bump.unwrap_or(1.0)));
    let emission_map = load(param("map_Ke"), true).map(|(t, _)| t);
    // Ke multiplies map_Ke; a map alone emits as it is.
    let emission = match (mtl.emissive.map(Vec3::from).filter(|e| e.is_finite()), &emission_map) {
        (Some(ke), _) => ke.max(Vec3::ZERO),
        (None, Some(_)) => Vec3::ONE,
        (None, None) => Vec3::ZERO,
    };
    let occlusion = rma.clone().map(|texture| (ChannelMap { texture, channel: 2 }, 1.0));
    MaterialTextures {
        alpha_mask: None,
        uv_transforms: Default::default(),
        emission,
        emission_map,
        occlusion,
        base_color,
        roughness: roughness.or_else(|| rma.clone().map(|texture| ChannelMap { texture, channel: 0 })),
        metallic: metallic.or_else(|| rma.map(|texture| ChannelMap { texture, channel: 1 })),
        normal,
    }
}

/// A map replaces its MTL constant (a `Kd` beside `map_Kd` is usually the exporter's default
/// grey): the constant becomes 1, which the texture multiplies. A map that failed to load is
/// not a map, so the constant stays.
fn textured_constants(mut material: Material, textures: Option<&MaterialTextures>) -> Material {
    if let Some(t) = textures {
        if t.base_color.is_some() {
            material.base_color = Vec3::ONE;
        }
        if t.roughness.is_some() {
            material.roughness = 1.0;
        }
        if t.metallic.is_some() {
            material.metallic = 1.0;
        }
    }
    material
}

/// An in-memory `BufRead` that counts the lines handed out, so a parse error can name its line.
struct LineCounter<'a> {
    rest: &'a [u8],
    lines: usize,
}

impl<'a> LineCounter<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        LineCounter { rest: bytes, lines: 0 }
    }
}

impl Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = buf.len().min(self.rest.len());
        buf[..n].copy_from_slice(&self.rest[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        Ok(self.rest)
    }

    fn consume(&mut self, amount: usize) {
        let (used, rest) = self.rest.split_at(amount.min(self.rest.len()));
        // A last line without '\n' is still a line.
        self.lines += used.iter().filter(|&&b| b == b'\n').count();
        if rest.is_empty() && used.last().is_some_and(|&b| b != b'\n') {
            self.lines += 1;
        }
        self.rest = rest;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// AFL's crash (tools/fuzz --afl): a relative index reaching back past the first texture
    /// coordinate overflowed tobj's arithmetic. Refused here with its line; valid relative,
    /// forward and attribute-less indices pass, as tobj reads them.
    #[test]
    fn face_indices_that_name_nothing_are_refused_with_their_line() {
        let ok = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/-1\nf -3//7 -2 -1\nf 1 2 4\nv 1 1 0\n";
        assert_eq!(check_indices(ok), Ok(()), "relative, forward, and normals where the file has none");
        let back = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/-3 3/1\n";
        assert_eq!(
            check_indices(back).unwrap_err(),
            "line 5: f index -3 names no texture coordinate (there are 1 before it)"
        );
        let past = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 18446744073709551\n";
        assert!(check_indices(past).unwrap_err().starts_with("line 4: f index 18446744073709551 names no vertex"));
        assert!(check_indices(b"v 0 0 0\nf 0 1 1\n").unwrap_err().contains("index 0 names no vertex"));
    }

    /// tobj splits words at any Unicode white space (`str::split_whitespace`): a no-break space
    /// (U+00A0) after `f` or `v` separates the keyword from the numbers. The checks split the
    /// same way, so such a face is checked (its index 7 slipped past them) and such a vertex
    /// counted (the face on it was refused as naming no vertex).
    #[test]
    fn lines_are_split_into_words_as_tobj_splits_them() {
        let face = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf\u{a0}1//7 2//1 3//1\n";
        assert_eq!(check_indices(face.as_bytes()).unwrap_err(), "line 5: f index 7 names no normal (there are 1)");
        let vertex = "v\u{a0}0 0 0\nv 1 0 0\u{2003}\nv 0 1 0\nf 1 2 3\n";
        assert_eq!(check_indices(vertex.as_bytes()), Ok(()));
        assert_eq!(check_is_obj("\u{a0}v\u{a0}0 0 0\n".as_bytes()), Ok(()));
        assert_eq!(count_short_faces("f\u{a0}1 2\n".as_bytes()), 1);
        assert_eq!(count_short_faces("f 1\u{a0}2 3\n".as_bytes()), 0);
    }

    #[test]
    fn text_and_binary_that_are_not_obj_are_refused() {
        assert_eq!(check_is_obj(b"# only a comment\n\n"), Ok(()));
        assert_eq!(check_is_obj(b"v 0 0 0\nwhatever\n"), Ok(()));
        assert_eq!(
            check_is_obj(b"# notes\nhello world\nsecond line\n").unwrap_err(),
            "line 2: no OBJ statement (v, f, o, ...) anywhere in the file"
        );
        assert!(check_is_obj(b"\x89PNG\r\n\x1a\n\0\0").unwrap_err().starts_with("binary data"));
    }

    #[test]
    fn shininess_maps_to_roughness_monotonically() {
        let material = |ns: f32| tobj::Material { shininess: Some(ns), ..Default::default() };
        let rough = convert_material(&material(0.0)).roughness;
        let mid = convert_material(&material(50.0)).roughness;
        let glossy = convert_material(&material(1000.0)).roughness;
        assert!((rough - 1.0).abs() < 1e-6);
        assert!(rough > mid && mid > glossy && glossy > 0.0);
    }

    #[test]
    fn pbr_extension_wins_and_is_clamped() {
        let mut mtl = tobj::Material { shininess: Some(10.0), diffuse: Some([2.0, 0.5, -1.0]), ..Default::default() };
        mtl.unknown_param.insert("Pr".into(), "0.25".into());
        mtl.unknown_param.insert("Pm".into(), "1.5".into());
        let m = convert_material(&mtl);
        assert_eq!(m, Material { base_color: Vec3::new(1.0, 0.5, 0.0), roughness: 0.25, metallic: 1.0 });
    }

    #[test]
    fn faces_with_one_or_two_corners_are_counted() {
        let obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1\nf 1 2\n  f   2 3\r\nf 1 2 3\nl 1 2\nfo 1\n# f 1\nf 1 2";
        assert_eq!(count_short_faces(obj), 4);
        assert_eq!(count_short_faces(b""), 0);
    }

    #[test]
    fn line_counter_counts_a_final_unterminated_line() {
        let mut reader = LineCounter::new(b"a\nb\nc");
        let lines: Vec<String> = (&mut reader).lines().map(Result::unwrap).collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(reader.lines, 3);
    }
}
