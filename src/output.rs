//! Writing frames to disk: PNG (display-referred, 8-bit sRGB) or EXR (scene-referred linear
//! float32). Files are written under a temporary name beside the target and renamed into place,
//! so a failed run never leaves a half-written image.
//!
//! The temporary file is created exclusively under a random name (`tempfile`), so no other user
//! can plant a file or a symlink there for the write to follow, and it is removed if the write
//! fails, the program panics, or SIGINT, SIGTERM, SIGHUP or SIGQUIT arrive while it exists. An
//! existing output keeps its mode; a read-only one is replaced only when asked (`--force`), and
//! an output that is one of the render's own inputs (the scene file, a mesh, a material library)
//! never is.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use tempfile::NamedTempFile;

use crate::renderer::Frame;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported output extension (use .png or .exr)")]
    Extension { path: PathBuf },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("{path}: the file exists and is read-only; pass --force to replace it")]
    ReadOnly { path: PathBuf },
    #[error("{path}: is an input of this render ({input}); choose another output file")]
    IsInput { path: PathBuf, input: PathBuf },
}

/// How `write_image_with` may treat an existing file.
#[derive(Clone, Debug, Default)]
pub struct WriteOptions {
    /// Replace an existing read-only file (its mode is kept, as for any replaced file).
    pub force: bool,
    /// Files the render read (`Scene::sources`): the output must be none of them.
    pub inputs: Vec<PathBuf>,
    /// How the image was made (scene, size, methods, samples, version, device), as key and
    /// value: written into an EXR header as `umbra:KEY` text attributes, so the file says it.
    pub provenance: Vec<(String, String)>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Exr,
}

impl ImageFormat {
    pub fn from_path(path: &Path) -> Result<ImageFormat, OutputError> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("exr") => Ok(ImageFormat::Exr),
            _ => Err(OutputError::Extension { path: path.to_owned() }),
        }
    }
}

/// Refuses an output that could never be written as asked: an unknown extension, a read-only
/// existing file without `force`, or one of `options.inputs` (the same file, however named:
/// compared by device and inode, so links and `./` spellings are caught).
/// `write_image_with` checks again; calling this before rendering fails fast.
pub fn check_output(path: &Path, options: &WriteOptions) -> Result<(), OutputError> {
    existing_output(path, options).map(drop)
}

/// `check_output`, returning the existing file's permissions, if there is one.
fn existing_output(path: &Path, options: &WriteOptions) -> Result<Option<fs::Permissions>, OutputError> {
    ImageFormat::from_path(path)?;
    let Ok(existing) = fs::metadata(path) else {
        return Ok(None); // nothing there (or nothing we can see): nothing to protect
    };
    for input in &options.inputs {
        if fs::metadata(input).is_ok_and(|m| same_file(&m, &existing)) {
            return Err(OutputError::IsInput { path: path.to_owned(), input: input.clone() });
        }
    }
    if existing.permissions().readonly() && !options.force {
        return Err(OutputError::ReadOnly { path: path.to_owned() });
    }
    let permissions = existing.permissions();
    // The replacement takes the file's read/write/execute bits, never set-id bits.
    #[cfg(unix)]
    let permissions = {
        use std::os::unix::fs::PermissionsExt;
        fs::Permissions::from_mode(permissions.mode() & 0o777)
    };
    Ok(Some(permissions))
}

#[cfg(unix)]
fn same_file(a: &fs::Metadata, b: &fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(_: &fs::Metadata, _: &fs::Metadata) -> bool {
    false
}

/// Writes `frame` to `path` atomically. 8-bit frames go to PNG as they are; float frames go to
/// EXR as they are, or to PNG clamped to 0..=1 (debug views already mapped for display).
/// `options` says what may be replaced (see `check_output`).
pub fn write_image_with(frame: &Frame, path: &Path, options: &WriteOptions) -> Result<(), OutputError> {
    let format = ImageFormat::from_path(path)?;
    let existing_mode = existing_output(path, options)?;
    let fail = |message: String| OutputError::Write { path: path.to_owned(), message };
    let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let tmp = cleanup::create(dir, &file_name).map_err(|e| fail(format!("cannot create a temporary file: {e}")))?;
    let written = match format {
        ImageFormat::Png => write_png(frame, &tmp),
        ImageFormat::Exr => write_exr(frame, &tmp, &options.provenance),
    }
    .and_then(|()| {
        if let Some(mode) = existing_mode {
            tmp.as_file().set_permissions(mode).map_err(|e| format!("cannot keep the file's mode: {e}"))?;
        }
        tmp.as_file().sync_all().map_err(|e| e.to_string())
    });
    if let Err(message) = written {
        cleanup::discard(tmp);
        return Err(fail(message));
    }
    cleanup::persist(tmp, path).map_err(|e| fail(format!("cannot move the finished image into place: {e}")))
}

/// Writes `bytes` to `path` atomically: a temporary file beside it, created exclusively with
/// the mode a new file gets (0666 less the umask), removed on failure or on a signal that ends
/// the process (as for images), then renamed into place. For every other file umbra writes
/// (bench results, charts).
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write as _;
    let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    let mut tmp = cleanup::create(dir, &file_name)?;
    if let Err(e) = tmp.write_all(bytes).and_then(|()| tmp.as_file().sync_all()) {
        cleanup::discard(tmp);
        return Err(e);
    }
    cleanup::persist(tmp, path)
}

/// Writes a set of files that belong together (a bench run's results and charts) all or
/// nothing: every file goes to a temporary file beside its target first, and only when all are
/// written and synced are they renamed into place. A failure on any (a full disk) removes the
/// temporary files and leaves every target as it was, so a directory never mixes one run's
/// chart with another's results. The error names the file that failed.
pub fn write_files_atomic(files: &[(PathBuf, Vec<u8>)]) -> std::io::Result<()> {
    use std::io::Write as _;
    let mut written = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let dir = match path.parent() {
            Some(dir) if !dir.as_os_str().is_empty() => dir,
            _ => Path::new("."),
        };
        let result = cleanup::create(dir, &file_name).and_then(|mut tmp| {
            match tmp.write_all(bytes).and_then(|()| tmp.as_file().sync_all()) {
                Ok(()) => Ok(tmp),
                Err(e) => {
                    cleanup::discard(tmp);
                    Err(e)
                }
            }
        });
        match result {
            Ok(tmp) => written.push(tmp),
            Err(e) => {
                written.into_iter().for_each(cleanup::discard);
                return Err(std::io::Error::new(e.kind(), format!("{}: {e}", path.display())));
            }
        }
    }
    for (tmp, (path, _)) in written.into_iter().zip(files) {
        cleanup::persist(tmp, path).map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
    }
    Ok(())
}

/// Writes `text` to standard output now (flushed): a failure (a full disk, `/dev/full`) is an
/// error for the caller to report, where `print!` would panic. A closed pipe never gets here:
/// the binary ends on SIGPIPE as other Unix tools do.
pub fn print_stdout(text: &str) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| std::io::Error::new(e.kind(), format!("cannot write to standard output: {e}")))
}

fn write_png(frame: &Frame, tmp: &NamedTempFile) -> Result<(), String> {
    let (width, height, bytes) = match frame {
        Frame::Rgba8 { width, height, pixels } => (*width, *height, pixels.clone()),
        Frame::Rgba32F { width, height, pixels } => {
            (*width, *height, pixels.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8).collect())
        }
    };
    let mut img = image::RgbaImage::from_raw(width, height, bytes).ok_or("frame size does not match its pixels")?;
    for p in img.pixels_mut() {
        p.0[3] = 255;
    }
    let mut out = BufWriter::new(tmp.as_file());
    image::DynamicImage::ImageRgba8(img)
        .to_rgb8()
        .write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    out.flush().map_err(|e| e.to_string())
}

/// EXR text attributes hold Latin-1 without NUL; anything else becomes `?`.
fn exr_text(text: &str) -> exr::prelude::Text {
    let clean: String = text.chars().map(|c| if (' '..='~').contains(&c) { c } else { '?' }).collect();
    exr::prelude::Text::new_or_none(&clean).unwrap_or_else(|| exr::prelude::Text::from("?"))
}

/// Float32 RGB with ZIP compression in blocks of 16 lines (lossless; RLE saved 2 % on renders,
/// whose noise and gradients leave few runs), and `provenance` as `umbra:KEY` text attributes.
fn write_exr(frame: &Frame, tmp: &NamedTempFile, provenance: &[(String, String)]) -> Result<(), String> {
    use exr::prelude::*;
    let Frame::Rgba32F { width, height, pixels } = frame else {
        return Err("EXR needs a linear float frame".into());
    };
    let w = *width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y)| {
        let i = (y * w + x) * 4;
        (pixels[i], pixels[i + 1], pixels[i + 2])
    });
    let mut image = Image::from_encoded_channels((w, *height as usize), Encoding::SMALL_LOSSLESS, channels);
    let attributes = &mut image.layer_data.attributes;
    attributes.software_name = Some(exr_text(&format!("umbra {}", env!("CARGO_PKG_VERSION"))));
    for (key, value) in provenance {
        attributes.other.insert(exr_text(&format!("umbra:{key}")), AttributeValue::Text(exr_text(value)));
    }
    image.write().to_buffered(BufWriter::new(tmp.as_file())).map_err(|e| e.to_string())?;
    sort_exr_attributes(tmp.as_file()).map_err(|e| format!("ordering the EXR header: {e}"))
}

/// Puts the header attributes of the single-part EXR in `file` in name order, in place, as
/// OpenEXR's own writer orders them: exr writes `other` attributes in the order of a `HashMap`,
/// which changes from run to run, so the same render would not give the same bytes twice. The
/// header keeps its length, so the offsets after it stay right.
fn sort_exr_attributes(mut file: &fs::File) -> std::io::Result<()> {
    use std::io::{Read, Seek, SeekFrom};
    /// More header than any umbra writes (a few hundred bytes).
    const MAX_HEADER: u64 = 1 << 20;
    file.seek(SeekFrom::Start(0))?;
    let mut head = Vec::new();
    file.take(MAX_HEADER).read_to_end(&mut head)?;
    let mut attributes = exr_attributes(&head)?;
    let length = attributes.iter().map(|a| a.bytes.len()).sum::<usize>();
    attributes.sort_by_key(|a| a.name);
    let sorted: Vec<u8> = attributes.iter().flat_map(|a| a.bytes.iter().copied()).collect();
    debug_assert_eq!(sorted.len(), length);
    file.seek(SeekFrom::Start(8))?;
    file.write_all(&sorted)?;
    file.flush()
}

/// One header attribute of an EXR: its name and all its bytes (name, type, size, value).
struct ExrAttribute<'a> {
    name: &'a [u8],
    bytes: &'a [u8],
}

/// The attributes of the single-part EXR header at the start of `head`, in file order, from
/// byte 8 up to the empty name that ends the header.
fn exr_attributes(head: &[u8]) -> std::io::Result<Vec<ExrAttribute<'_>>> {
    let bad = |what: &str, at: usize| std::io::Error::other(format!("{what} at byte {at}"));
    // Magic number, then the version word, whose bit 12 marks a multi-part file.
    if head.len() < 8 || head[..4] != [0x76, 0x2f, 0x31, 0x01] || head[5] & 0x10 != 0 {
        return Err(bad("not a single-part EXR", 0));
    }
    let nul = |from: usize| head.get(from..)?.iter().position(|&b| b == 0).map(|k| from + k);
    let mut attributes = Vec::new();
    let mut at = 8;
    loop {
        let name_end = nul(at).ok_or_else(|| bad("an unterminated attribute name", at))?;
        if name_end == at {
            return Ok(attributes); // the empty name that ends the header
        }
        let type_end = nul(name_end + 1).ok_or_else(|| bad("an unterminated attribute type", at))?;
        let size_bytes = head.get(type_end + 1..type_end + 5).ok_or_else(|| bad("a cut attribute", at))?;
        let size = u32::from_le_bytes(size_bytes.try_into().expect("four bytes")) as usize;
        let end = type_end + 5 + size;
        let bytes = head.get(at..end).ok_or_else(|| bad("a cut attribute", at))?;
        attributes.push(ExrAttribute { name: &head[at..name_end], bytes });
        at = end;
    }
}

/// Reads an RGB EXR as linear float RGBA rows (alpha 1); used by tests and tools.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<f32>), String> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| (resolution.width(), vec![0f32; resolution.width() * resolution.height() * 4]),
        |(w, data), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = (pos.y() * *w + pos.x()) * 4;
            data[i..i + 4].copy_from_slice(&[r, g, b, 1.0]);
        },
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    let size = image.layer_data.size;
    Ok((size.width() as u32, size.height() as u32, image.layer_data.channel_data.pixels.1))
}

/// Temporary files that exist right now, removed by a signal thread on SIGINT, SIGTERM, SIGHUP
/// (the terminal closed) or SIGQUIT before the process ends as the signal's default action
/// would end it.
///
/// The list's lock is held from creating a file until it is listed, and from renaming it until
/// it is struck off, so the signal thread never misses a file nor removes a finished image.
mod cleanup {
    use std::io;
    use std::path::{Path, PathBuf};
    use std::sync::{Mutex, MutexGuard, Once};

    use tempfile::NamedTempFile;

    static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
    static HANDLER: Once = Once::new();

    fn pending() -> MutexGuard<'static, Vec<PathBuf>> {
        PENDING.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Starts the signal thread, once per process.
    fn install_handler() {
        HANDLER.call_once(|| {
            use signal_hook::consts::{SIGHUP, SIGINT, SIGQUIT, SIGTERM};
            let unwatched = |e: io::Error| {
                log::warn!(
                    "cannot watch for SIGINT, SIGTERM, SIGHUP and SIGQUIT ({e}): an interrupted write may leave a \
                     temporary file"
                )
            };
            // A signal ignored when umbra started stays ignored (`nohup` ignores SIGHUP, a shell
            // SIGINT and SIGQUIT for a background job): watching it would let it end the run.
            let watched = [SIGINT, SIGTERM, SIGHUP, SIGQUIT].into_iter().filter(|&s| !ignored(s));
            let mut signals = match signal_hook::iterator::Signals::new(watched) {
                Ok(signals) => signals,
                Err(e) => return unwatched(e),
            };
            let spawned = std::thread::Builder::new().name("umbra-signals".into()).spawn(move || {
                if let Some(signal) = signals.forever().next() {
                    for path in pending().drain(..) {
                        let _ = std::fs::remove_file(path);
                    }
                    // Ends the process as the signal would have (killed by it), or exits with
                    // the shell's code for it if that fails.
                    let _ = signal_hook::low_level::emulate_default_handler(signal);
                    std::process::exit(128 + signal);
                }
            });
            if let Err(e) = spawned {
                unwatched(e);
            }
        });
    }

    /// Whether `signal`'s disposition is to be ignored.
    fn ignored(signal: i32) -> bool {
        // SAFETY: with no new action, sigaction only reads the current one into `old`.
        unsafe {
            let mut old: libc::sigaction = std::mem::zeroed();
            libc::sigaction(signal, std::ptr::null(), &mut old) == 0 && old.sa_sigaction == libc::SIG_IGN
        }
    }

    /// The longest file name: NAME_MAX on Linux and the BSDs.
    const NAME_MAX: usize = 255;

    /// A new empty file `.<name>.XXXXXX.tmp` in `dir`, created exclusively (never through an
    /// existing name or link), with the mode a new file gets (0666 less the umask), and listed.
    /// `<name>` is cut short where the whole would not fit in `NAME_MAX` bytes (an output named
    /// with 244 bytes or more).
    pub(super) fn create(dir: &Path, name: &str) -> io::Result<NamedTempFile> {
        install_handler();
        let prefix = format!(".{}.", fit(name, NAME_MAX - ".".len() - ".XXXXXX.tmp".len()));
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let mut pending = pending();
        let tmp = builder.tempfile_in(dir)?;
        pending.push(tmp.path().to_owned());
        Ok(tmp)
    }

    /// The longest start of `name` that is at most `bytes` long, cut between characters.
    fn fit(name: &str, bytes: usize) -> &str {
        let mut end = name.len().min(bytes);
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        &name[..end]
    }

    /// Removes a temporary file that will not be used.
    pub(super) fn discard(tmp: NamedTempFile) {
        let mut pending = pending();
        let path = tmp.path().to_owned();
        drop(tmp); // removes the file
        pending.retain(|p| *p != path);
    }

    /// Renames the temporary file to `target` (replacing a file or link there, never writing
    /// through a link), or removes it if that fails.
    pub(super) fn persist(tmp: NamedTempFile, target: &Path) -> io::Result<()> {
        let mut pending = pending();
        let path = tmp.path().to_owned();
        let result = tmp.persist(target).map(drop).map_err(|e| e.error); // on error the file is dropped: removed
        pending.retain(|p| *p != path);
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// exr keeps `umbra:` attributes in a `HashMap` (new hash keys per map), so without the
    /// sort two writes of one frame in one process order them differently.
    #[test]
    fn the_same_exr_twice_is_the_same_bytes_and_reads_back() {
        let (width, height) = (7u32, 5u32);
        let pixels: Vec<f32> = (0..width * height * 4).map(|i| i as f32 * 0.25 - 3.0).collect();
        let frame = Frame::Rgba32F { width, height, pixels: pixels.clone() };
        let provenance: Vec<(String, String)> = (0..12).map(|k| (format!("key{k}"), format!("value {k}"))).collect();
        let options = WriteOptions { provenance: provenance.clone(), ..Default::default() };
        let dir = tempfile::tempdir().unwrap();
        let paths = [dir.path().join("a.exr"), dir.path().join("b.exr")];
        for path in &paths {
            write_image_with(&frame, path, &options).unwrap();
        }
        let bytes = paths.each_ref().map(|p| fs::read(p).unwrap());
        assert!(bytes[0] == bytes[1], "two writes of one frame differ");

        let (w, h, read) = read_exr(&paths[0]).unwrap();
        assert_eq!((w, h), (width, height));
        for (i, (got, want)) in read.iter().zip(&pixels).enumerate() {
            let want = if i % 4 == 3 { 1.0 } else { *want };
            assert_eq!(*got, want, "float {i}");
        }
        let meta = exr::meta::MetaData::read_from_file(&paths[0], false).unwrap();
        let other = &meta.headers[0].own_attributes.other;
        for (key, value) in &provenance {
            let got = other.get(&exr::prelude::Text::from(format!("umbra:{key}").as_str()));
            assert_eq!(got, Some(&exr::prelude::AttributeValue::Text(exr::prelude::Text::from(value.as_str()))));
        }
        // In name order, as the sort put them.
        let names: Vec<&[u8]> = exr_attributes(&bytes[0]).unwrap().iter().map(|a| a.name).collect();
        assert!(names.len() > provenance.len());
        assert!(names.is_sorted(), "{:?}", names.iter().map(|n| String::from_utf8_lossy(n)).collect::<Vec<_>>());
    }

    /// A set of files is written whole or not at all: when one of them cannot be written, the
    /// others already written keep their old contents and no temporary file is left.
    #[test]
    fn a_set_of_files_is_written_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("results.csv"), dir.path().join("chart.png"));
        fs::write(&a, b"old csv").unwrap();
        fs::write(&b, b"old png").unwrap();
        // The third file's folder does not exist: its temporary file cannot be made.
        let missing = dir.path().join("gone").join("chart.svg");
        let set = vec![(a.clone(), b"new csv".to_vec()), (b.clone(), b"new png".to_vec()), (missing, b"svg".to_vec())];
        let err = write_files_atomic(&set).unwrap_err();
        assert!(err.to_string().contains("chart.svg"), "{err}");
        assert_eq!((fs::read(&a).unwrap(), fs::read(&b).unwrap()), (b"old csv".to_vec(), b"old png".to_vec()));
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2, "no temporary file left");
        write_files_atomic(&set[..2]).unwrap();
        assert_eq!((fs::read(&a).unwrap(), fs::read(&b).unwrap()), (b"new csv".to_vec(), b"new png".to_vec()));
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
    }
}
