//! Progress reporting from long library calls, drawn by whoever calls them.

/// Receives progress from long operations. The CLI draws bars; libraries pass [`Silent`].
pub trait Progress: Sync {
    /// A stage named `stage` of `total` steps begins.
    fn begin(&self, stage: &str, total: u64);
    /// `n` more steps of the current stage are done.
    fn advance(&self, n: u64);
    /// The current stage is over.
    fn end(&self);
}

/// Reports nothing.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {
    fn begin(&self, _stage: &str, _total: u64) {}
    fn advance(&self, _n: u64) {}
    fn end(&self) {}
}
