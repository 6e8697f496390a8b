//! How a test says it cannot run here (no GPU adapter, no shared data, no Node), so
//! that no skip is silent: the reason goes to stderr, is appended to the file named by
//! `RELIT_SKIP_LOG` (`scripts/test.sh` prints that list at the end), and with
//! `RELIT_NO_SKIPS=1` the skip fails the test instead. For the workspace's tests; not
//! part of the library's API.

use std::io::Write;

/// Record that the calling test skips its remaining checks because of `why`; panics
/// instead when `RELIT_NO_SKIPS=1`.
#[doc(hidden)]
pub fn skipping(why: &str) {
    let test = std::thread::current()
        .name()
        .unwrap_or("a test")
        .to_string();
    if std::env::var("RELIT_NO_SKIPS").is_ok_and(|v| v == "1") {
        panic!("{test} cannot run here (RELIT_NO_SKIPS=1): {why}");
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
