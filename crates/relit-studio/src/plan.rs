//! Light plans: which directional lights a capture is taken under.
//!
//! | plan string          | lights                                                        |
//! |----------------------|---------------------------------------------------------------|
//! | `grid:70x140`        | θ×φ grid cell centres over the whole sphere (seed 004)        |
//! | `fibonacci:3072`     | nearly uniform over the sphere (seed 002)                     |
//! | `hemisphere:300`     | nearly uniform over the upper hemisphere z > 0 (an RTI dome)  |
//! | `list:FILE`          | the directions in FILE                                        |
//!
//! A list file is an RTI `.lp` file (count line, then `name x y z`), a JSON array of
//! `[x, y, z]` triples, or plain text with one `x y z` (or `x,y,z`) per line, `#`
//! starting a comment. Directions point toward the light in the light frame and are
//! normalised; a zero or non-finite one is an error naming its line.

use crate::{invalid, parse_error, Result};
use relit::sphere::{self, Vec3};
use std::path::Path;

/// Most lights a plan may hold: far beyond any capture, small enough to stop typos
/// such as `fibonacci:3072000000` before they allocate.
pub const MAX_LIGHTS: usize = 1_000_000;

/// A set of light directions.
#[derive(Clone, Debug, PartialEq)]
pub enum LightPlan {
    Grid { theta: usize, phi: usize },
    Fibonacci(usize),
    Hemisphere(usize),
    List(Vec<Vec3>),
}

impl LightPlan {
    /// Parse a plan string (see the module docs); `list:` files are read now.
    pub fn parse(spec: &str) -> Result<LightPlan> {
        let (kind, arg) = spec.split_once(':').ok_or_else(|| {
            parse_error(format!("bad light plan `{spec}`: expected grid:TxP, fibonacci:N, hemisphere:N or list:FILE"))
        })?;
        let count = |s: &str| -> Result<usize> {
            let n: usize = s.trim().parse().map_err(|_| {
                parse_error(format!("bad light plan `{spec}`: `{s}` is not a count"))
            })?;
            if n == 0 || n > MAX_LIGHTS {
                return Err(invalid(format!(
                    "bad light plan `{spec}`: the count must be 1 to {MAX_LIGHTS}"
                )));
            }
            Ok(n)
        };
        let plan = match kind.trim().to_ascii_lowercase().as_str() {
            "grid" => {
                let (t, p) = arg
                    .split_once(['x', 'X', '*'])
                    .ok_or_else(|| parse_error(format!("bad light plan `{spec}`: expected grid:THETAxPHI, e.g. grid:70x140")))?;
                let (theta, phi) = (count(t)?, count(p)?);
                if theta.saturating_mul(phi) > MAX_LIGHTS {
                    return Err(invalid(format!("bad light plan `{spec}`: more than {MAX_LIGHTS} lights")));
                }
                LightPlan::Grid { theta, phi }
            }
            "fibonacci" | "sphere" => LightPlan::Fibonacci(count(arg)?),
            "hemisphere" | "dome" => LightPlan::Hemisphere(count(arg)?),
            "list" => LightPlan::List(read_list(Path::new(arg.trim()))?),
            other => {
                return Err(parse_error(format!(
                    "unknown light plan `{other}` in `{spec}` (known: grid, fibonacci, hemisphere, list)"
                )))
            }
        };
        Ok(plan)
    }

    /// The file a `list:FILE` plan string reads, `None` for the other plans.
    pub fn list_file(spec: &str) -> Option<&Path> {
        let (kind, arg) = spec.split_once(':')?;
        kind.trim()
            .eq_ignore_ascii_case("list")
            .then(|| Path::new(arg.trim()))
    }

    /// The unit light directions, in capture order.
    pub fn directions(&self) -> Vec<Vec3> {
        match self {
            LightPlan::Grid { theta, phi } => sphere::grid(*theta, *phi),
            LightPlan::Fibonacci(n) => sphere::fibonacci(*n),
            LightPlan::Hemisphere(n) => sphere::hemisphere_fibonacci(*n),
            LightPlan::List(dirs) => dirs.clone(),
        }
    }

    /// The number of lights.
    pub fn len(&self) -> usize {
        match self {
            LightPlan::Grid { theta, phi } => theta * phi,
            LightPlan::Fibonacci(n) | LightPlan::Hemisphere(n) => *n,
            LightPlan::List(dirs) => dirs.len(),
        }
    }

    /// Whether the plan has no lights (only an empty list can).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// A short description for summaries.
    pub fn describe(&self) -> String {
        match self {
            LightPlan::Grid { theta, phi } => format!("{theta}×{phi} θφ grid"),
            LightPlan::Fibonacci(n) => format!("{n} Fibonacci directions over the sphere"),
            LightPlan::Hemisphere(n) => {
                format!("{n} Fibonacci directions over the upper hemisphere")
            }
            LightPlan::List(d) => format!("{} listed directions", d.len()),
        }
    }
}

/// Read a list of directions (see the module docs for the accepted forms).
pub fn read_list(path: &Path) -> Result<Vec<Vec3>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| crate::io_error(path, "read the light list", e))?;
    parse_list(&text, &path.display().to_string())
}

/// Parse the text of a list of directions; `origin` names it in messages.
pub fn parse_list(text: &str, origin: &str) -> Result<Vec<Vec3>> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .unwrap_or("");
    let dirs: Vec<Vec3> = if first.starts_with('[') {
        let triples: Vec<[f64; 3]> = serde_json::from_str(text)
            .map_err(|e| parse_error(format!("{origin}: line {}: {e}", e.line())))?;
        triples
            .iter()
            .enumerate()
            .map(|(i, t)| {
                Vec3::from(*t).normalized().ok_or_else(|| {
                    parse_error(format!(
                        "{origin}: entry {i}: the direction has no length or is not finite"
                    ))
                })
            })
            .collect::<Result<_>>()?
    } else if first.parse::<usize>().is_ok() {
        relit::capture::lp::parse(text, origin)?
            .into_iter()
            .map(|e| e.direction)
            .collect()
    } else {
        let mut dirs = Vec::new();
        for (number, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let parts: Vec<&str> = line
                .split([',', ' ', '\t'])
                .filter(|s| !s.is_empty())
                .collect();
            let values: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
            if parts.len() != 3 || values.len() != 3 {
                return Err(parse_error(format!(
                    "{origin}: line {}: expected `x y z`, found `{line}`",
                    number + 1
                )));
            }
            let d = Vec3::new(values[0], values[1], values[2])
                .normalized()
                .ok_or_else(|| {
                    parse_error(format!(
                        "{origin}: line {}: the direction has no length or is not finite",
                        number + 1
                    ))
                })?;
            dirs.push(d);
        }
        dirs
    };
    if dirs.is_empty() {
        return Err(invalid(format!("{origin}: the light list is empty")));
    }
    if dirs.len() > MAX_LIGHTS {
        return Err(invalid(format!("{origin}: more than {MAX_LIGHTS} lights")));
    }
    Ok(dirs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_strings_parse() {
        assert_eq!(
            LightPlan::parse("grid:70x140").unwrap(),
            LightPlan::Grid {
                theta: 70,
                phi: 140
            }
        );
        assert_eq!(
            LightPlan::parse("grid:7x14").unwrap().directions().len(),
            98
        );
        assert_eq!(LightPlan::parse("fibonacci:3072").unwrap().len(), 3072);
        let dome = LightPlan::parse("hemisphere:30").unwrap().directions();
        assert!(dome.iter().all(|d| d.z > 0.0));
        for bad in [
            "grid:70",
            "grid:0x5",
            "fibonacci:-3",
            "fibonacci:abc",
            "hemisphere:2000000",
            "spiral:30",
            "30",
            "list:/no/such/file.lp",
        ] {
            assert!(LightPlan::parse(bad).is_err(), "{bad} should fail");
        }
    }

    #[test]
    fn list_files_in_three_forms() {
        let lp = parse_list("2\na.png 0 0 2\nb.png 1 0 0\n", "t").unwrap();
        assert_eq!(lp, vec![Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 0.0)]);
        let json = parse_list("[[0, 3, 0], [0, 0, -1]]", "t").unwrap();
        assert_eq!(json[0], Vec3::new(0.0, 1.0, 0.0));
        let plain = parse_list("# lights\n0 0 1\n1,0,0 # east\n\n", "t").unwrap();
        assert_eq!(plain.len(), 2);
        let err = parse_list("0 0 1\n0 0 0\n", "t").unwrap_err().to_string();
        assert!(err.contains("line 2"), "{err}");
        assert!(parse_list("0 0\n", "t").is_err());
        assert!(parse_list("", "t").is_err());
    }
}
