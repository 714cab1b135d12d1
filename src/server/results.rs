//! A job's result files under `results/`: their names, sizes and removal, and the check at
//! start that every result file belongs to a job the store holds.

use std::path::{Path, PathBuf};

/// Where a job's result files live: `png` and `exr` (the final image, or the latest
/// preview), and `ppmstate` (a progressive job's running state, while it may resume).
pub fn result_path(data: &Path, id: i64, ext: &str) -> PathBuf {
    data.join("results").join(format!("{id}.{ext}"))
}

/// Result files of jobs the store does not hold (it lost rows, or was replaced) are moved
/// to `results/orphaned/` and said loudly: never served as another job's, never deleted.
pub fn set_aside_orphans(data: &Path, ids: &std::collections::HashSet<i64>) {
    let dir = data.join("results");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    let mut moved = 0;
    // One folder a start, so that an earlier start's orphans are never overwritten.
    let orphaned = dir
        .join("orphaned")
        .join(format!("{:.0}", super::store::now() * 1e3));
    for e in entries.flatten() {
        let path = e.path();
        if !path.is_file() {
            continue;
        }
        let id = path
            .file_stem()
            .and_then(|s| s.to_str())
            .and_then(|s| s.parse::<i64>().ok());
        if id.is_none_or(|id| ids.contains(&id)) {
            continue; // not a result file (temporaries), or a known job's
        }
        let to = orphaned.join(e.file_name());
        match std::fs::create_dir_all(&orphaned).and_then(|_| std::fs::rename(&path, &to)) {
            Ok(()) => moved += 1,
            Err(err) => tracing::error!("setting aside {}: {err}", path.display()),
        }
    }
    if moved > 0 {
        tracing::error!(
            "the store and the data folder disagree: {moved} result files belong to no job in \
             the store (it lost rows?); moved to {}",
            orphaned.display()
        );
    }
}

/// Bytes a job's result files take on disk now.
pub fn result_bytes(data: &Path, id: i64) -> u64 {
    ["png", "exr", "ppmstate"]
        .iter()
        .filter_map(|ext| std::fs::metadata(result_path(data, id, ext)).ok())
        .map(|m| m.len())
        .sum()
}

/// Remove a job's result files (`which`: extensions, see [`result_path`]); missing ones are
/// fine.
pub fn remove_results(data: &Path, id: i64, which: &[&str]) {
    for ext in which {
        let _ = std::fs::remove_file(result_path(data, id, ext));
    }
}
