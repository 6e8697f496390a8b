//! How a test says it cannot run here (no GPU adapter, no shared data, no Node), so
//! that no skip is silent: the reason goes to stderr, is appended to the file named by
//! `RELIT_SKIP_LOG` (`scripts/test.sh` prints that list at the end), and where a skip
//! would hide a broken path it fails the test instead:
//!
//! * with `RELIT_NO_SKIPS=1`, every skip fails;
//! * in CI (`CI=true`, as `.ci/run` sets), a missing *tool* fails (software Vulkan,
//!   Chromium, Node, playwright-core: `scripts/test.sh` installs them first), and so
//!   does missing *shared data* on a machine that has the `../shared` folder at all
//!   (an item or client missing from it is a broken set-up, not an absent one). A CI
//!   machine without `../shared` logs those skips: the data are not the project's to
//!   install.
//!
//! For the workspace's tests; not part of the library's API.

use std::io::Write;
use std::path::{Path, PathBuf};

/// Record that the calling test skips its remaining checks because a tool or device is
/// missing (`why`); panics instead in CI or with `RELIT_NO_SKIPS=1`.
#[doc(hidden)]
pub fn skipping(why: &str) {
    skip(why, in_ci());
}

/// Record that the calling test skips its remaining checks because the shared file or
/// folder `missing` (under `../shared`) is not there; panics instead with
/// `RELIT_NO_SKIPS=1`, and in CI when the `shared` folder itself exists.
#[doc(hidden)]
pub fn skipping_shared(missing: &Path) {
    skip(
        &format!("{} is not present", missing.display()),
        in_ci() && shared_folder_present(missing),
    );
}

/// Whether the nearest ancestor of `path` named `shared` exists.
fn shared_folder_present(path: &Path) -> bool {
    path.ancestors()
        .find(|a| a.file_name().is_some_and(|n| n == "shared"))
        .is_some_and(|shared| shared.is_dir())
}

/// The file or folder `relative` under the shared folder beside the repository
/// (`../shared`), or `None` after [`skipping_shared`] when it is not there.
#[doc(hidden)]
pub fn shared(relative: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared")
        .join(relative);
    if path.exists() {
        Some(path)
    } else {
        skipping_shared(&path);
        None
    }
}

/// Whether the tests run in CI: `CI` set to `true` or `1`.
fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v.eq_ignore_ascii_case("true") || v == "1")
}

fn skip(why: &str, fail: bool) {
    let test = std::thread::current()
        .name()
        .unwrap_or("a test")
        .to_string();
    if std::env::var("RELIT_NO_SKIPS").is_ok_and(|v| v == "1") {
        panic!("{test} cannot run here (RELIT_NO_SKIPS=1): {why}");
    }
    if fail {
        panic!("{test} cannot run here, and in CI (CI=true) a skip is a failure: {why}");
    }
    eprintln!("skipping ({test}): {why}");
    if let Some(log) = std::env::var_os("RELIT_SKIP_LOG") {
        // Best effort: a log that cannot be written must not fail the test.
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(log)
        {
            let _ = writeln!(f, "{test}: {why}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_data_counts_as_a_broken_set_up_only_where_shared_exists() {
        let dir = tempfile::tempdir().unwrap();
        let item = dir.path().join("shared/data/realrti/item1/dirs.lp");
        assert!(!shared_folder_present(&item));
        std::fs::create_dir(dir.path().join("shared")).unwrap();
        assert!(shared_folder_present(&item));
        // Through `..` components, as the tests build their paths.
        std::fs::create_dir_all(dir.path().join("repo/crates/x")).unwrap();
        let relative = dir
            .path()
            .join("repo/crates/x/../../../shared/data/models/a.obj");
        assert!(shared_folder_present(&relative));
        assert!(!shared_folder_present(Path::new("/nonexistent/data/a.lp")));
    }
}
