//! RTI light-position files (`.lp`), as RTIBuilder and light domes write them.
//!
//! ```text
//! 60
//! image00.jpg -0.0270679 -0.286359 0.95774
//! image 01.jpg 0.0782479 -0.20073 0.976517
//! ```
//!
//! A count line, then `filename x y z` per image. Leading and trailing spaces, Windows
//! line endings and file names with spaces are accepted; names resolve relative to the
//! `.lp` file's folder; vectors are normalised. Axes: x right, y up, z toward the camera.

use super::{check_images, resolve_image_path, Capture, CapturedLight, ImageSource};
use crate::camera::Projection;
use crate::sphere::Vec3;
use crate::{Error, Result};
use std::collections::HashMap;
use std::path::Path;

/// One parsed line: the image name, its light vector, and the 1-based line number.
#[derive(Clone, Debug, PartialEq)]
pub struct LpEntry {
    pub name: String,
    pub direction: Vec3,
    pub line: usize,
}

/// Parse the text of an `.lp` file. `origin` names the file in messages.
pub fn parse(text: &str, origin: &str) -> Result<Vec<LpEntry>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    let (count_line, count_text) = lines
        .next()
        .ok_or_else(|| Error::parse(format!("{origin}: empty file (expected an image count)")))?;
    let count: usize = count_text.parse().map_err(|_| {
        Error::parse(format!(
            "{origin}: line {count_line}: expected the number of images, found `{count_text}`"
        ))
    })?;
    let mut entries = Vec::with_capacity(count.min(100_000));
    let mut seen: HashMap<String, usize> = HashMap::new();
    for (line, text) in lines {
        let tokens: Vec<&str> = text.split_whitespace().collect();
        if tokens.len() < 4 {
            return Err(Error::parse(format!(
                "{origin}: line {line}: expected `filename x y z`, found `{text}`"
            )));
        }
        let n = tokens.len();
        let mut xyz = [0.0f64; 3];
        for (k, tok) in tokens[n - 3..].iter().enumerate() {
            xyz[k] = tok.parse().map_err(|_| {
                Error::parse(format!(
                    "{origin}: line {line}: `{tok}` is not a number (expected `filename x y z`)"
                ))
            })?;
        }
        // The name is everything before the three numbers, inner spaces kept.
        let name_end = {
            let mut rest = text;
            for _ in 0..3 {
                rest = rest.trim_end();
                rest = &rest[..rest.rfind(char::is_whitespace).unwrap_or(0)];
            }
            rest.trim_end().len()
        };
        let name = text[..name_end].trim().to_string();
        let v = Vec3::from(xyz);
        let direction = v.normalized().ok_or_else(|| {
            Error::parse(format!(
                "{origin}: line {line}: light vector ({}, {}, {}) of `{name}` has no direction (zero, NaN or infinite)",
                xyz[0], xyz[1], xyz[2]
            ))
        })?;
        if let Some(first) = seen.insert(name.clone(), line) {
            return Err(Error::parse(format!(
                "{origin}: line {line}: image `{name}` is listed twice (first on line {first})"
            )));
        }
        entries.push(LpEntry {
            name,
            direction,
            line,
        });
    }
    if entries.len() != count {
        return Err(Error::parse(format!(
            "{origin}: line {count_line}: the count says {count} images but the file lists {}",
            entries.len()
        )));
    }
    Ok(entries)
}

/// Read an `.lp` file and check its images (existence, one shared size).
pub fn read(path: &Path) -> Result<Capture> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, "read", e))?;
    let text = String::from_utf8_lossy(&bytes);
    let origin = path.display().to_string();
    let entries = parse(&text, &origin)?;
    let folder = path.parent().unwrap_or(Path::new("."));
    let lights: Vec<CapturedLight> = entries
        .iter()
        .map(|e| CapturedLight {
            image: ImageSource::File {
                path: resolve_image_path(folder, &e.name),
                encoding: None,
            },
            direction: e.direction,
            intensity: [1.0; 3],
        })
        .collect();
    let (width, height) =
        check_images(&lights, &|i| format!("{origin}: line {}", entries[i].line))?;
    Ok(Capture {
        lights,
        width,
        height,
        projection: Projection::Planar { fov_y_deg: None },
        camera: None,
        depth: None,
        mask: None,
        origin,
        source_files: vec![path.to_path_buf()],
    })
}

/// The text of an `.lp` file for `names` and `directions`.
pub fn format(names: &[String], directions: &[Vec3]) -> String {
    let mut out = format!("{}\n", names.len());
    for (n, d) in names.iter().zip(directions) {
        out.push_str(&format!("{n} {:.9} {:.9} {:.9}\n", d.x, d.y, d.z));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accepts_what_rti_tools_write() {
        let text = "\u{feff}  3   \r\n image00.jpg -0.0270679 -0.286359 0.95774\r\nmy photo 01.jpg  0 0 2\r\n\r\n\timg2.JPG 1e-1 0.0 -0.5 \r\n";
        let e = parse(text, "t.lp").unwrap();
        assert_eq!(e.len(), 3);
        assert_eq!(e[0].name, "image00.jpg");
        assert_eq!(e[1].name, "my photo 01.jpg");
        assert_eq!(e[1].direction, Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(e[2].line, 5);
        assert!((e[0].direction.length() - 1.0).abs() < 1e-12);
        assert!((e[2].direction.x - 0.1 / (0.01f64 + 0.25).sqrt()).abs() < 1e-12);
    }

    fn err(text: &str) -> String {
        parse(text, "t.lp").unwrap_err().to_string()
    }

    #[test]
    fn each_bad_case_names_its_line() {
        assert!(err("3\na.jpg 0 0 1\nb.jpg 0 1 0\n")
            .contains("line 1: the count says 3 images but the file lists 2"));
        assert!(err("1\na.jpg 0 0 1\nb.jpg 0 1 0\n").contains("line 1"));
        assert!(err("2\na.jpg 0 0 1\nb.jpg 0 0 0\n").contains("line 3: light vector (0, 0, 0)"));
        assert!(err("2\na.jpg 0 0 1\nb.jpg NaN 0 1\n").contains("line 3"));
        assert!(err("2\na.jpg 0 0 1\nb.jpg inf 0 1\n").contains("line 3"));
        assert!(err("2\na.jpg 0 0 1\na.jpg 0 1 0\n")
            .contains("line 3: image `a.jpg` is listed twice (first on line 2)"));
        assert!(err("2\na.jpg 0 0 1\nb.jpg 0 x 1\n").contains("line 3: `x` is not a number"));
        assert!(err("2\na.jpg 0 0 1\nb.jpg 0 1\n").contains("line 3: expected `filename x y z`"));
        assert!(err("two\n").contains("line 1: expected the number of images"));
        assert!(err("  \n").contains("empty file"));
    }

    #[test]
    fn missing_and_mismatched_images_are_reported_by_line() {
        let dir = tempfile::tempdir().unwrap();
        let img = crate::image::ImageRgb::new(4, 3);
        crate::image::save(&dir.path().join("a.png"), &img, 0.0).unwrap();
        crate::image::save(
            &dir.path().join("b c.png"),
            &crate::image::ImageRgb::new(5, 3),
            0.0,
        )
        .unwrap();
        let lp = dir.path().join("dirs.lp");
        std::fs::write(&lp, "2\na.png 0 0 1\nmissing.png 0 1 1\n").unwrap();
        let e = read(&lp).unwrap_err().to_string();
        assert!(
            e.contains("line 3") && e.contains("missing.png") && e.contains("not found"),
            "{e}"
        );
        std::fs::write(&lp, "2\na.png 0 0 1\nb c.png 0 1 1\n").unwrap();
        let e = read(&lp).unwrap_err().to_string();
        assert!(
            e.contains("line 3") && e.contains("5×3") && e.contains("4×3"),
            "{e}"
        );
        std::fs::write(&lp, "1\nC:\\captures\\a.png 0 0 1\n").unwrap();
        let cap = read(&lp).unwrap();
        assert_eq!((cap.width, cap.height, cap.len()), (4, 3, 1));
        assert_eq!(cap.input_files(), [lp.clone(), dir.path().join("a.png")]);
    }
}
