//! Writing what the CLI produces (`cook`'s asset, `render`'s PNG, `report`'s files) without ever
//! losing data the user typed a path to. One place, used by every subcommand that writes:
//!
//! - an output that is one of the inputs read (same file, through any symlink or hard link), or a
//!   file inside a frame set being read that the set's folder or pattern would pick up next time,
//!   is refused before anything is written;
//! - a symlink is written through: the file it points at is replaced, the link stays;
//! - a regular file (or a new one) is written to a temporary file beside it, synced and renamed
//!   over it, so a failure or a kill never leaves a partial output under the final name;
//! - anything else that exists (`/dev/null`, `/dev/full`, a FIFO, a terminal) is opened and
//!   written directly: never renamed over, so a device stays a device and write errors surface;
//! - every temporary file is registered, and removed on any failure and by the SIGINT/SIGTERM
//!   handler (`install_signal_handlers`), which then exits with 130/143.
//!
//! `VDBCOOK_TEST_WRITE_DELAY_MS` (test-only, undocumented for users) sleeps after the temporary
//! file is complete and before the rename, so tests can interrupt a write in progress.

use std::ffi::CString;
use std::io::Write;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicPtr, Ordering};

use vdbcook_vdb::sequence::Frame;

use crate::errors::CliError;

/// Temporary files that exist (or are about to), as leaked C strings a signal handler may read.
/// A fixed table: lock-free and async-signal-safe. A process writes one output at a time.
const SLOTS: usize = 16;
static TEMPS: [AtomicPtr<libc::c_char>; SLOTS] =
    [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];

extern "C" fn on_signal(sig: libc::c_int) {
    for slot in &TEMPS {
        let p = slot.load(Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: `p` is a leaked, never-freed NUL-terminated string; unlink is
            // async-signal-safe.
            unsafe {
                libc::unlink(p);
            }
        }
    }
    // SAFETY: _exit is async-signal-safe.
    unsafe { libc::_exit(128 + sig) }
}

/// Removes registered temporary files on SIGINT and SIGTERM, then exits 130 / 143.
pub fn install_signal_handlers() {
    // SAFETY: installing a handler that only calls async-signal-safe functions.
    unsafe {
        let handler: extern "C" fn(libc::c_int) = on_signal;
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = handler as usize;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGINT, &sa, std::ptr::null_mut());
        libc::sigaction(libc::SIGTERM, &sa, std::ptr::null_mut());
    }
}

/// A registered temporary file: removed when dropped unless `keep` (after the rename).
struct Temp {
    path: PathBuf,
    slot: Option<usize>,
    keep: bool,
}

impl Temp {
    fn register(path: PathBuf) -> Temp {
        let mut slot = None;
        if let Ok(c) = CString::new(path.as_os_str().as_bytes()) {
            // Leaked on purpose: a signal handler may be reading it at any moment.
            let p = c.into_raw();
            for (i, s) in TEMPS.iter().enumerate() {
                if s.compare_exchange(std::ptr::null_mut(), p, Ordering::SeqCst, Ordering::SeqCst)
                    .is_ok()
                {
                    slot = Some(i);
                    break;
                }
            }
        }
        Temp {
            path,
            slot,
            keep: false,
        }
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        if let Some(i) = self.slot {
            TEMPS[i].store(std::ptr::null_mut(), Ordering::SeqCst);
        }
        if !self.keep {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

fn io_err(path: &Path, m: impl Into<String>) -> CliError {
    CliError::Vdb(vdbcook_vdb::VdbError::new(
        vdbcook_vdb::ErrorKind::Io,
        path,
        m,
    ))
}

/// Follows symlinks (also dangling ones, whose target is then created) to the path to write.
fn resolve_links(out: &Path) -> Result<PathBuf, CliError> {
    let mut p = out.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&p)
                    .map_err(|e| io_err(out, format!("cannot read the symlink: {e}")))?;
                p = match p.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(io_err(out, "too many levels of symbolic links"))
}

/// The folder a path lives in, canonical (symlinks resolved), if it exists.
fn canonical_dir(p: &Path) -> Option<PathBuf> {
    let dir = p
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::canonicalize(dir).ok()
}

/// A file name with its digits removed: `smoke.0001.vdb` → `smoke..vdb` (the set's pattern).
fn without_digits(p: &Path) -> Option<String> {
    let n = p.file_name()?.to_string_lossy();
    n.bytes()
        .any(|b| b.is_ascii_digit())
        .then(|| n.chars().filter(|c| !c.is_ascii_digit()).collect())
}

/// Refuses an output that would replace or join what is being read: any input file (by device
/// and inode, so symlinks and hard links count), or — for frames that came from a folder,
/// pattern or glob — a name in the same folder that the set would pick up (a `.vdb` in a folder
/// input; the same name up to its digits for a pattern or glob).
pub fn refuse_inputs(
    out: &Path,
    frames: &[Frame],
    inputs: &[String],
    what: &str,
) -> Result<(), CliError> {
    let target = resolve_links(out)?;
    let refuse = |m: String| Err(io_err(out, m));
    if let Ok(om) = std::fs::metadata(&target) {
        if om.is_file() {
            for f in frames {
                if let Ok(m) = std::fs::metadata(&f.path) {
                    if m.dev() == om.dev() && m.ino() == om.ino() {
                        return refuse(format!(
                            "the {what} would overwrite the input {}; choose another output path",
                            f.path.display()
                        ));
                    }
                }
            }
        }
    }
    // Inputs that were files as given are not sets; expanded ones are.
    let out_dir = canonical_dir(&target);
    let out_pat = without_digits(&target);
    for input in inputs {
        let ip = Path::new(input);
        if ip.is_dir() {
            let is_vdb = target
                .extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("vdb"));
            if is_vdb && out_dir.is_some() && std::fs::canonicalize(ip).ok() == out_dir {
                return refuse(format!(
                    "the {what} would be written into the frame folder {input} being read (as a .vdb the next read would take for a frame); choose another output path"
                ));
            }
        }
    }
    for f in frames {
        if inputs.iter().any(|i| Path::new(i) == f.path) {
            continue;
        }
        if out_pat.is_some()
            && without_digits(&f.path) == out_pat
            && out_dir.is_some()
            && canonical_dir(&f.path) == out_dir
        {
            return refuse(format!(
                "the {what} would be written into the frame set being read (it matches its frame {}); choose another output path",
                f.path.display()
            ));
        }
    }
    Ok(())
}

/// Whether `out` (through symlinks) exists and is not a regular file or folder: a device, FIFO
/// or socket, which is written directly.
pub fn is_special(out: &Path) -> bool {
    resolve_links(out)
        .ok()
        .and_then(|t| std::fs::metadata(t).ok())
        .is_some_and(|m| {
            let ft = m.file_type();
            ft.is_char_device() || ft.is_block_device() || ft.is_fifo() || ft.is_socket()
        })
}

/// Checks, before any long work, that `out` can be written: its folder exists and takes files
/// (or it is a device or FIFO), and it is not a folder itself. `what` names it in errors.
pub fn check_writable(out: &Path, what: &str) -> Result<(), CliError> {
    let target = resolve_links(out)?;
    if let Ok(m) = std::fs::metadata(&target) {
        if m.is_dir() {
            return Err(io_err(
                out,
                format!("is a folder; give a file name for the {what}"),
            ));
        }
        if !m.is_file() {
            return Ok(());
        }
    }
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    match std::fs::metadata(dir) {
        Err(_) => Err(io_err(
            out,
            format!(
                "cannot write the {what}: the folder {} does not exist",
                dir.display()
            ),
        )),
        Ok(m) if !m.is_dir() => Err(io_err(
            out,
            format!("cannot write the {what}: {} is not a folder", dir.display()),
        )),
        Ok(_) => {
            // A probe file: permissions, read-only mounts and full inode tables all show here.
            static PROBE: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
            let probe = dir.join(format!(
                ".vdbcook-probe-{}-{}",
                std::process::id(),
                PROBE.fetch_add(1, Ordering::Relaxed)
            ));
            let tmp = Temp::register(probe);
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp.path)
                .map(|_| ())
                .map_err(|e| {
                    io_err(
                        out,
                        format!(
                            "cannot write the {what} into the folder {}: {e}",
                            dir.display()
                        ),
                    )
                })
        }
    }
}

/// Writes `bytes` to `out` as the module documentation says; `what` names it in errors
/// ("asset", "PNG").
pub fn write(out: &Path, bytes: &[u8], what: &str) -> Result<(), CliError> {
    let target = resolve_links(out)?;
    let fail = |e: &dyn std::fmt::Display| io_err(out, format!("cannot write the {what}: {e}"));
    match std::fs::metadata(&target) {
        Ok(m) if m.is_dir() => {
            return Err(io_err(
                out,
                format!("is a folder; give a file name for the {what}"),
            ))
        }
        Ok(m) if !m.is_file() => {
            // Devices, FIFOs, sockets: written in place, never replaced.
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .open(&target)
                .map_err(|e| fail(&e))?;
            return f
                .write_all(bytes)
                .and_then(|_| f.flush())
                .map_err(|e| fail(&e));
        }
        _ => {}
    }
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = target
        .file_name()
        .ok_or_else(|| io_err(out, "output path has no file name"))?;
    // Unique per process and per write, so concurrent writers (threads or processes) of one
    // name never share a temporary; the rename makes the last one win whole.
    static SERIAL: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let mut tmp = Temp::register(dir.join(format!(
        ".{}.partial-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        SERIAL.fetch_add(1, Ordering::Relaxed)
    )));
    let result = (|| {
        // A leftover from an earlier process with the same id is stale.
        let _ = std::fs::remove_file(&tmp.path);
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp.path)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        if let Some(ms) = std::env::var("VDBCOOK_TEST_WRITE_DELAY_MS")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
        {
            std::thread::sleep(std::time::Duration::from_millis(ms));
        }
        std::fs::rename(&tmp.path, &target)
    })();
    match result {
        Ok(()) => {
            tmp.keep = true;
            Ok(())
        }
        Err(e) => Err(fail(&e)),
    }
}
