//! The GPU engine's error: what failed, in words a user can act on.

use std::fmt;

/// Why the GPU engine could not do what was asked.
#[derive(Debug)]
#[non_exhaustive]
pub enum GpuError {
    /// No GPU adapter exists (no driver, no device): the CPU engine is the fallback.
    NoAdapter(String),
    /// The adapter refused a device, or the device reported an error (out of memory,
    /// validation, device lost).
    Device(String),
    /// The maps do not fit the adapter's buffer limits.
    TooLarge(String),
    /// The request is valid for relit but this engine does not do it (a light type).
    Unsupported(String),
    /// The input is unusable (from the relit library: bad light, bad region, bad basis).
    Relit(relit::Error),
}

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GpuError::NoAdapter(why) => write!(f, "no GPU adapter: {why}"),
            GpuError::Device(why) => write!(f, "GPU device error: {why}"),
            GpuError::TooLarge(why) => write!(f, "too large for the GPU: {why}"),
            GpuError::Unsupported(why) => write!(f, "not supported by the GPU engine: {why}"),
            GpuError::Relit(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for GpuError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            GpuError::Relit(e) => Some(e),
            _ => None,
        }
    }
}

impl From<relit::Error> for GpuError {
    fn from(e: relit::Error) -> Self {
        GpuError::Relit(e)
    }
}

/// Shorthand for results of this crate.
pub type Result<T, E = GpuError> = std::result::Result<T, E>;

/// An invalid-input error from a message.
pub(crate) fn invalid(message: impl Into<String>) -> GpuError {
    GpuError::Relit(relit::Error::new(relit::ErrorKind::InvalidInput, message))
}
