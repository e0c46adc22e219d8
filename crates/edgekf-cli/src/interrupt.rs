//! Ctrl-C (SIGINT) or SIGTERM: one line on stderr saying what was and was not written, and exit
//! code 130 (143 for SIGTERM), within moments in every phase of a command (loading, simulating,
//! designing, writing).
//!
//! The signal handler only writes a byte to a pipe (async-signal-safe). A watcher thread waits
//! on the pipe; on a signal it takes the lock that every commit holds (so a directory whose
//! staged files are being moved into place is finished first, and no commit starts after it),
//! removes the temporary files of the writes not committed, prints the line and ends the
//! process. No phase has to poll for the interrupt, so none can miss it.

use std::fs;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::Mutex;

use anyhow::Result;
use edgekf_io::Staged;

/// The pipe's write end, for the handler (−1 before [`install`]).
static WRITE_FD: AtomicI32 = AtomicI32::new(-1);

/// Set by the watcher as soon as a SIGINT arrives: from then on the watcher ends the process.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// What has been written, and where writes are under way.
struct Log {
    /// Directories (or files) whose outputs are in place.
    written: Vec<PathBuf>,
    /// Directories being written: (directory, whether it existed before).
    staging: Vec<(PathBuf, bool)>,
    /// Child processes (`edgekf swarm`): asked to stop, then killed.
    children: Vec<u32>,
    /// Paths a killed child may leave (its staging directory, logs): removed after it ended;
    /// with `true`, only when empty.
    leftovers: Vec<(PathBuf, bool)>,
}

static LOG: Mutex<Log> = Mutex::new(Log {
    written: Vec::new(),
    staging: Vec::new(),
    children: Vec::new(),
    leftovers: Vec::new(),
});

fn log() -> std::sync::MutexGuard<'static, Log> {
    LOG.lock().unwrap_or_else(|e| e.into_inner())
}

extern "C" fn on_signal(signal: libc::c_int) {
    let fd = WRITE_FD.load(Ordering::Relaxed);
    if fd >= 0 {
        let b = signal as u8;
        // SAFETY: write(2) is async-signal-safe; the buffer is one valid byte.
        unsafe {
            libc::write(fd, (&b as *const u8).cast(), 1);
        }
    }
}

/// Installs the handler and starts the watcher. Call first thing in `main`.
pub fn install() {
    let mut fds = [0 as libc::c_int; 2];
    // SAFETY: pipe(2) fills the two descriptors of a valid array.
    if unsafe { libc::pipe(fds.as_mut_ptr()) } != 0 {
        return;
    }
    for fd in fds {
        // SAFETY: fcntl on descriptors we own.
        unsafe {
            libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
        }
    }
    let read_fd = fds[0];
    if std::thread::Builder::new()
        .name("sigint".into())
        .spawn(move || watch(read_fd))
        .is_err()
    {
        return;
    }
    WRITE_FD.store(fds[1], Ordering::Relaxed);
    // SAFETY: a zeroed sigaction with an extern "C" handler that only calls write(2).
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        sa.sa_flags = libc::SA_RESTART;
        libc::sigemptyset(&mut sa.sa_mask);
        libc::sigaction(libc::SIGINT, &sa, std::ptr::null_mut());
        libc::sigaction(libc::SIGTERM, &sa, std::ptr::null_mut());
    }
}

/// The watcher: blocks until the handler writes, then ends the process.
fn watch(fd: libc::c_int) {
    let mut b = 0u8;
    loop {
        // SAFETY: read(2) into one valid byte.
        let n = unsafe { libc::read(fd, (&mut b as *mut u8).cast(), 1) };
        if n == 1 {
            break;
        }
        if n < 0 && std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted {
            continue;
        }
        return;
    }
    INTERRUPTED.store(true, Ordering::SeqCst);
    // Held until the process ends: a commit under way finishes first, none starts after.
    let log = log();
    stop_children(&log.children);
    for (path, only_empty) in &log.leftovers {
        if *only_empty {
            let _ = fs::remove_dir(path);
        } else if path.is_dir() {
            let _ = fs::remove_dir_all(path);
        } else {
            let _ = fs::remove_file(path);
        }
    }
    for (dir, existed) in &log.staging {
        // A figure may still be being encoded into the staging directory: once the directory
        // is gone, no staged file can appear (a file created between the listing and the
        // removal of the directory makes it fail: try again).
        let stage = edgekf_io::staging_dir(dir);
        for _ in 0..1000 {
            let _ = fs::remove_dir_all(&stage);
            if !stage.exists() {
                break;
            }
        }
        remove_temporaries(dir);
        if !existed {
            let _ = fs::remove_dir(dir);
        }
    }
    let (msg, code) = last_line(&log.written, libc::c_int::from(b));
    // Another thread may be half-way through an `eprintln!` ("wrote DIR" without its newline
    // yet: stderr is unbuffered, one line is several writes): its lock, held until the exit,
    // makes this line start a line of its own.
    let _stderr = std::io::stderr().lock();
    // SAFETY: write(2) to stderr of a valid buffer, then _exit(2) (no destructors, no atexit:
    // other threads may be anywhere).
    unsafe {
        libc::write(2, msg.as_ptr().cast(), msg.len());
        libc::_exit(code);
    }
}

/// The line that ends the process after `signal`, saying what was `written`, and the exit code.
fn last_line(written: &[PathBuf], signal: libc::c_int) -> (String, i32) {
    let line = match written {
        [] => "nothing was written".to_string(),
        w => format!(
            "{} {} written completely; nothing else was written",
            w.iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            if w.len() == 1 { "was" } else { "were" }
        ),
    };
    // A progress bar may hold the line: start a new one.
    let lead = if std::io::stderr().is_terminal() {
        "\n"
    } else {
        ""
    };
    let (how, code) = if signal == libc::SIGTERM {
        ("terminated (SIGTERM)", 128 + libc::SIGTERM)
    } else {
        ("interrupted (Ctrl-C)", 130)
    };
    (format!("{lead}edgekf: {how}: {line}\n"), code)
}

/// Asks the children to stop (SIGINT: a world finishes a commit under way and removes its
/// staged files), waits up to 3 s, then kills those still running (SIGKILL) and reaps them.
fn stop_children(children: &[u32]) {
    let pids: Vec<libc::pid_t> = children.iter().filter_map(|&p| p.try_into().ok()).collect();
    for &p in &pids {
        // SAFETY: kill(2) on a pid of our own child.
        unsafe {
            libc::kill(p, libc::SIGINT);
        }
    }
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(3);
    let mut alive = pids;
    while !alive.is_empty() && std::time::Instant::now() < deadline {
        // SAFETY: waitpid(2) with WNOHANG on our own children; a null status pointer is allowed.
        alive.retain(|&p| unsafe { libc::waitpid(p, std::ptr::null_mut(), libc::WNOHANG) } == 0);
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    for p in alive {
        // SAFETY: as above.
        unsafe {
            libc::kill(p, libc::SIGKILL);
            libc::waitpid(p, std::ptr::null_mut(), 0);
        }
    }
}

/// Registers a child process: Ctrl-C stops it before this process ends.
#[cfg_attr(not(feature = "swarm"), allow(dead_code))]
pub fn child(pid: u32) {
    log().children.push(pid);
}

/// Registers a path (a directory or a file) that Ctrl-C removes once the children are stopped.
#[cfg_attr(not(feature = "swarm"), allow(dead_code))]
pub fn remove_on_interrupt(path: &Path) {
    log().leftovers.push((path.to_path_buf(), false));
}

/// Registers a directory that Ctrl-C removes once the children are stopped, if it is empty.
#[cfg_attr(not(feature = "swarm"), allow(dead_code))]
pub fn remove_if_empty_on_interrupt(path: &Path) {
    log().leftovers.push((path.to_path_buf(), true));
}

/// The hidden temporaries of the writes that do not stage (`.NAME.PID.tmp`, written inside a
/// [`critical`] section, so normally none).
fn remove_temporaries(dir: &Path) {
    let Ok(rd) = fs::read_dir(dir) else { return };
    for d in rd.filter_map(|d| d.ok()) {
        let name = d.file_name().to_string_lossy().to_string();
        if name.starts_with('.') && name.contains(".tmp") {
            let _ = fs::remove_file(d.path());
        }
    }
}

/// After an interrupt the watcher ends the process, with its line: the main thread must not
/// end it first (with an error its cleanup caused, or with success), so it waits here.
pub fn settle() {
    if INTERRUPTED.load(Ordering::SeqCst) {
        loop {
            std::thread::park();
        }
    }
}

/// [`Staged::new`], with `dir` registered so that Ctrl-C removes what was staged in it.
///
/// # Errors
/// As [`Staged::new`].
pub fn stage(dir: &Path) -> Result<Staged> {
    // The log is held while the staging directory is created: a Ctrl-C then either finds it
    // (and removes it) or holds the log first, and this never creates it (a staging directory
    // created after the watcher's cleanup was left behind: the interrupt stress test).
    let mut log = log();
    let existed = dir.exists();
    log.staging.push((dir.to_path_buf(), existed));
    Ok(Staged::new(dir)?)
}

/// Runs `write` (the renames that put a directory's files in place, or a small atomic write) as
/// one step that Ctrl-C does not cut, then records `what` as written.
///
/// # Errors
/// As `write`.
pub fn critical<T>(what: &Path, write: impl FnOnce() -> Result<T>) -> Result<T> {
    let mut log = log();
    let out = write()?;
    log.staging.retain(|(d, _)| d != what);
    if !log.written.iter().any(|w| w == what) {
        log.written.push(what.to_path_buf());
    }
    Ok(out)
}
