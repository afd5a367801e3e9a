//! Temporary files a killed run left behind (SIGKILL, a node lost: no
//! chance to remove them), found and removed by the next run that writes
//! into the same folder.
//!
//! A temporary file is named `.NAME.HOST-PID.N.tmp`. One of this machine
//! whose process is gone is removed at once; one of another machine (a
//! render farm's shared folder) only once it is a day old, since that
//! machine's processes cannot be seen from here.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, SystemTime};

/// How old another machine's temporary file must be to count as left
/// behind: far longer than writing any one file takes.
const OTHER_HOST_AGE: Duration = Duration::from_secs(24 * 3600);

/// Folders already swept by this process, and the files removed.
static SWEPT: Mutex<(Vec<PathBuf>, Vec<PathBuf>)> = Mutex::new((Vec::new(), Vec::new()));

/// This machine's name as temporary files carry it (no `.` or `-`, which
/// separate the name's parts).
pub(super) fn host() -> &'static str {
    static HOST: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    HOST.get_or_init(|| {
        let name = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        let name: String = name
            .trim()
            .chars()
            .map(|c| if c == '.' || c == '-' { '_' } else { c })
            .collect();
        if name.is_empty() {
            "host".to_string()
        } else {
            name
        }
    })
}

/// Removes, once per folder and process, the temporary files in `dir`
/// that killed runs left behind.
pub(super) fn sweep_once(dir: &Path) {
    let mut swept = SWEPT.lock().unwrap_or_else(PoisonError::into_inner);
    if swept.0.iter().any(|d| d == dir) {
        return;
    }
    swept.0.push(dir.to_path_buf());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let own = std::process::id();
    for entry in entries.flatten() {
        let path = entry.path();
        let Some((host, pid)) = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(writer_of)
        else {
            continue;
        };
        let left_behind = if host == self::host() {
            pid != own && !Path::new(&format!("/proc/{pid}")).exists()
        } else {
            entry
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| SystemTime::now().duration_since(t).ok())
                .is_some_and(|age| age > OTHER_HOST_AGE)
        };
        if left_behind && std::fs::remove_file(&path).is_ok() {
            swept.1.push(path);
        }
    }
}

/// The files removed since the last call, for the program to say so.
pub fn take_removed_temporaries() -> Vec<PathBuf> {
    let mut swept = SWEPT.lock().unwrap_or_else(PoisonError::into_inner);
    std::mem::take(&mut swept.1)
}

/// The machine and process that wrote temporary file `name`
/// (`.NAME.HOST-PID.N.tmp`), if it is one.
fn writer_of(name: &str) -> Option<(&str, u32)> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (rest, count) = rest.rsplit_once('.')?;
    count.parse::<u64>().ok()?;
    let (rest, writer) = rest.rsplit_once('.')?;
    if rest.is_empty() {
        return None;
    }
    let (host, pid) = writer.rsplit_once('-')?;
    Some((host, pid.parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_give_their_writer() {
        assert_eq!(writer_of(".f_0001.png.box-123.4.tmp"), Some(("box", 123)));
        assert_eq!(writer_of(".a.b.c.box-7.0.tmp"), Some(("box", 7)));
        for other in [
            ".box-123.4.tmp",
            "f.png.box-1.2.tmp",
            ".f.png.box-x.2.tmp",
            ".f.png.tmp",
        ] {
            assert_eq!(writer_of(other), None, "{other}");
        }
    }

    /// A process id no process has here.
    fn dead_pid() -> u32 {
        (4_000_000..)
            .find(|pid| !Path::new(&format!("/proc/{pid}")).exists())
            .unwrap()
    }

    #[test]
    fn a_dead_writers_files_go_and_a_live_ones_stay() {
        let dir = tempfile::tempdir().unwrap();
        let dead = dir
            .path()
            .join(format!(".f.png.{}-{}.0.tmp", host(), dead_pid()));
        // Process 1 always runs; another machine's file is young.
        let live = dir.path().join(format!(".f.png.{}-1.0.tmp", host()));
        let elsewhere = dir.path().join(".f.png.otherbox-5.0.tmp");
        let unrelated = dir.path().join(".hidden.tmp");
        for file in [&dead, &live, &elsewhere, &unrelated] {
            std::fs::write(file, b"partial").unwrap();
        }
        sweep_once(dir.path());
        assert!(!dead.exists());
        assert!(live.exists() && elsewhere.exists() && unrelated.exists());
        assert!(take_removed_temporaries().contains(&dead));
        // Once per folder: a file left later by this run's own writes is
        // not this sweep's business.
        std::fs::write(&dead, b"again").unwrap();
        sweep_once(dir.path());
        assert!(dead.exists());
    }
}
