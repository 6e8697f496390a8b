//! Regions of interest: the window of pixels a frame is computed for.

use crate::error::{invalid, Result};

/// A rectangle of pixels, `x, y` its top-left corner (image convention: y down).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Roi {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

impl Roi {
    /// The whole `width × height` image.
    pub fn full(width: usize, height: usize) -> Self {
        Self {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// Parse `x,y,w,h`.
    pub fn parse(s: &str) -> Result<Self> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let numbers: Option<Vec<usize>> = parts.iter().map(|p| p.parse().ok()).collect();
        match numbers.as_deref() {
            Some(&[x, y, width, height]) => Ok(Self {
                x,
                y,
                width,
                height,
            }),
            _ => Err(invalid(format!(
                "bad region `{s}`: expected `x,y,width,height` in pixels"
            ))),
        }
    }

    /// Check that the region is non-empty and inside a `width × height` image.
    pub fn validate(&self, width: usize, height: usize) -> Result<()> {
        let inside = self.width > 0
            && self.height > 0
            && self.x.checked_add(self.width).is_some_and(|r| r <= width)
            && self.y.checked_add(self.height).is_some_and(|b| b <= height);
        if inside {
            Ok(())
        } else {
            Err(invalid(format!(
                "region {}×{} at ({}, {}) is empty or leaves the {width}×{height} image",
                self.width, self.height, self.x, self.y
            )))
        }
    }

    /// Pixels in the region.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_checks_bounds() {
        let r = Roi::parse("1, 2,3,4").unwrap();
        assert_eq!((r.x, r.y, r.width, r.height), (1, 2, 3, 4));
        assert!(r.validate(4, 6).is_ok());
        assert!(r.validate(3, 6).is_err());
        assert!(Roi::parse("1,2,3").is_err());
        assert!(Roi::parse("a,2,3,4").is_err());
        assert!(Roi::full(5, 5).validate(5, 5).is_ok());
        assert!(Roi::parse("0,0,0,1").unwrap().validate(5, 5).is_err());
        let huge = Roi {
            x: usize::MAX,
            y: 0,
            width: 2,
            height: 1,
        };
        assert!(huge.validate(5, 5).is_err());
    }
}
