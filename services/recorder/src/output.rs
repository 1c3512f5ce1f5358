//! Where a recording goes. A recorder never truncates a recording: one that is restarted (after
//! a crash, a full disk, or a swap in the field) writes the next free `<stem>.<n>.mcap` beside
//! the file it was given, so the part written before stays readable.

use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};

/// Most parts tried before giving up (a recorder crash-looping on a full disk stops here).
const MAX_PARTS: u32 = 1000;

/// Creates `path`, or, if a non-empty file is there already, the first of `<stem>.1.<ext>`,
/// `<stem>.2.<ext>`, ... that does not exist. An empty file (a recorder that died before writing
/// a byte) is reused. Returns the file and the path it has.
pub fn create_unused(path: &Path) -> io::Result<(File, PathBuf)> {
    if std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() == 0) {
        return Ok((File::create(path)?, path.to_path_buf()));
    }
    for n in 0..=MAX_PARTS {
        let candidate = part_path(path, n);
        match OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&candidate)
        {
            Ok(f) => return Ok((f, candidate)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        format!("{} and its {MAX_PARTS} parts exist already", path.display()),
    ))
}

/// Removes a recording and the parts a restarted recorder wrote beside it: a new run that is
/// given the same file replaces the run before, and must not leave its parts to be read as its
/// own.
pub fn remove_with_parts(path: &Path) -> io::Result<()> {
    for n in 0..=MAX_PARTS {
        match std::fs::remove_file(part_path(path, n)) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound && n > 0 => return Ok(()),
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// Part `n` of a recording: `dir/run.mcap` itself for 0, else `dir/run.<n>.mcap` (`dir/run.<n>`
/// without an extension).
fn part_path(path: &Path, n: u32) -> PathBuf {
    if n == 0 {
        return path.to_path_buf();
    }
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let name = match path.extension() {
        Some(ext) => format!("{stem}.{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}.{n}"),
    };
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_existing_recording_is_kept_and_the_next_part_is_written_beside_it() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let run = dir.join("run.mcap");
        let (_, first) = create_unused(&run).unwrap();
        assert_eq!(first, run);
        // Nothing written yet: a restart reuses the empty file.
        assert_eq!(create_unused(&run).unwrap().1, run);
        std::fs::write(&run, b"recorded before the crash").unwrap();
        let (_, second) = create_unused(&run).unwrap();
        assert_eq!(second, dir.join("run.1.mcap"));
        std::fs::write(&second, b"x").unwrap();
        assert_eq!(create_unused(&run).unwrap().1, dir.join("run.2.mcap"));
        assert_eq!(
            std::fs::read(&run).unwrap(),
            b"recorded before the crash",
            "the first part must survive"
        );
        remove_with_parts(&run).unwrap();
        assert_eq!(std::fs::read_dir(dir).unwrap().count(), 0);
    }
}
