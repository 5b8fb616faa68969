//! The fuzz targets' scratch folder.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Prefix of the scratch folders' names, before the process id.
const PREFIX: &str = "unz-fuzz-";

/// One folder for the whole fuzzing process, `unz-fuzz-<pid>` in the system's temporary
/// folder, for a run's `run/` and `out/`. A process ends without removing it (libFuzzer
/// exits), and a fork-mode campaign starts a process per job: the folders of processes
/// that have ended are removed when a process makes its own, so none outlives the next.
fn scratch() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let tmp = std::env::temp_dir();
        for entry in std::fs::read_dir(&tmp).into_iter().flatten().flatten() {
            let name = entry.file_name();
            let pid = (name.to_str())
                .and_then(|n| n.strip_prefix(PREFIX))
                .and_then(|p| p.parse::<u32>().ok());
            if pid.is_some_and(|pid| !Path::new(&format!("/proc/{pid}")).exists()) {
                let _ = std::fs::remove_dir_all(entry.path());
            }
        }
        let dir = tmp.join(format!("{PREFIX}{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

/// The scratch folder's `run/` and `out/`, emptied (the first created): a run written
/// there and processed into `out/` leaves nothing of the input before.
pub fn run_and_out() -> (PathBuf, PathBuf) {
    let dir = scratch();
    let (run, out) = (dir.join("run"), dir.join("out"));
    let _ = std::fs::remove_dir_all(&out);
    let _ = std::fs::remove_dir_all(&run);
    std::fs::create_dir_all(&run).unwrap();
    (run, out)
}
