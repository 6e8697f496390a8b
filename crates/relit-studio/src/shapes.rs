//! Triangle meshes of simple shapes, in object space, with texture coordinates in
//! metres along the surface (see [`crate::texture`]).
//!
//! Everything the tracer renders is triangles: analytic primitives would need their own
//! intersection code in the BVH for little gain at the sizes the studio renders, while a
//! tessellated sphere or cylinder with interpolated normals shades smoothly.

use crate::math::{v3, Transform, V3};
use std::f32::consts::{PI, TAU};

/// One triangle: positions, shading normals (unit), texture coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub p: [V3; 3],
    pub n: [V3; 3],
    pub uv: [[f32; 2]; 3],
}

impl Triangle {
    /// A flat triangle (every shading normal equals the face normal).
    pub fn flat(p: [V3; 3], uv: [[f32; 2]; 3]) -> Triangle {
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
        Triangle { p, n: [n; 3], uv }
    }

    /// The triangle mapped by `t` (normals by its inverse transpose).
    pub fn transformed(&self, t: &Transform) -> Triangle {
        Triangle {
            p: self.p.map(|p| t.point(p)),
            n: self.n.map(|n| t.normal(n)),
            uv: self.uv,
        }
    }
}

/// A list of triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub triangles: Vec<Triangle>,
}

impl Mesh {
    /// The mesh mapped by `t`.
    pub fn transformed(&self, t: &Transform) -> Mesh {
        Mesh {
            triangles: self
                .triangles
                .iter()
                .map(|tri| tri.transformed(t))
                .collect(),
        }
    }

    fn quad_uv(&mut self, corners: [V3; 4], uv: [[f32; 2]; 4]) {
        self.triangles.push(Triangle::flat(
            [corners[0], corners[1], corners[2]],
            [uv[0], uv[1], uv[2]],
        ));
        self.triangles.push(Triangle::flat(
            [corners[0], corners[2], corners[3]],
            [uv[0], uv[2], uv[3]],
        ));
    }
}

/// A parallelogram from `origin` spanned by `u` and `v`; it faces `u × v`.
pub fn quad(origin: V3, u: V3, v: V3) -> Mesh {
    let (lu, lv) = (u.length(), v.length());
    let mut m = Mesh::default();
    m.quad_uv(
        [origin, origin + u, origin + u + v, origin + v],
        [[0.0, 0.0], [lu, 0.0], [lu, lv], [0.0, lv]],
    );
    m
}

/// A parallelogram wall with rectangular openings. `holes` are `[u0, v0, u1, v1]` in
/// metres along `u` and `v`. The wall is cut into the grid of every hole edge and the
/// cells outside all holes are kept, so openings may overlap or touch the border.
pub fn wall_with_holes(origin: V3, u: V3, v: V3, holes: &[[f32; 4]]) -> Mesh {
    let (lu, lv) = (u.length(), v.length());
    let (du, dv) = (u * (1.0 / lu), v * (1.0 / lv));
    let mut us = vec![0.0, lu];
    let mut vs = vec![0.0, lv];
    for h in holes {
        us.extend([h[0].clamp(0.0, lu), h[2].clamp(0.0, lu)]);
        vs.extend([h[1].clamp(0.0, lv), h[3].clamp(0.0, lv)]);
    }
    for list in [&mut us, &mut vs] {
        list.sort_by(f32::total_cmp);
        list.dedup();
    }
    let mut m = Mesh::default();
    for j in 0..vs.len() - 1 {
        for i in 0..us.len() - 1 {
            let (cu, cv) = (0.5 * (us[i] + us[i + 1]), 0.5 * (vs[j] + vs[j + 1]));
            if holes
                .iter()
                .any(|h| cu > h[0] && cu < h[2] && cv > h[1] && cv < h[3])
            {
                continue;
            }
            let at = |a: f32, b: f32| origin + du * a + dv * b;
            m.quad_uv(
                [
                    at(us[i], vs[j]),
                    at(us[i + 1], vs[j]),
                    at(us[i + 1], vs[j + 1]),
                    at(us[i], vs[j + 1]),
                ],
                [
                    [us[i], vs[j]],
                    [us[i + 1], vs[j]],
                    [us[i + 1], vs[j + 1]],
                    [us[i], vs[j + 1]],
                ],
            );
        }
    }
    m
}

/// An axis-aligned box from `min` to `max` with outward faces.
pub fn cuboid(min: V3, max: V3) -> Mesh {
    let s = max - min;
    let (x, y, z) = (v3(s.x, 0.0, 0.0), v3(0.0, s.y, 0.0), v3(0.0, 0.0, s.z));
    let mut m = Mesh::default();
    for face in [
        quad(min, z, y),     // −x
        quad(min + x, y, z), // +x
        quad(min, x, z),     // −y
        quad(min + y, z, x), // +y
        quad(min, y, x),     // −z
        quad(min + z, x, y), // +z
    ] {
        m.triangles.extend(face.triangles);
    }
    m
}

/// A cylinder around +y from `y = 0` to `height`, `segments` sides, smooth normals,
/// with end caps when `caps`.
pub fn cylinder(radius: f32, height: f32, segments: usize, caps: bool) -> Mesh {
    let segments = segments.max(3);
    let circumference = TAU * radius;
    let ring = |k: usize| {
        let a = TAU * k as f32 / segments as f32;
        v3(a.sin(), 0.0, a.cos())
    };
    let mut m = Mesh::default();
    for k in 0..segments {
        let (d0, d1) = (ring(k), ring(k + 1));
        let (u0, u1) = (
            circumference * k as f32 / segments as f32,
            circumference * (k + 1) as f32 / segments as f32,
        );
        let (b0, b1) = (d0 * radius, d1 * radius);
        let (t0, t1) = (b0 + v3(0.0, height, 0.0), b1 + v3(0.0, height, 0.0));
        m.triangles.push(Triangle {
            p: [b0, b1, t1],
            n: [d0, d1, d1],
            uv: [[u0, 0.0], [u1, 0.0], [u1, height]],
        });
        m.triangles.push(Triangle {
            p: [b0, t1, t0],
            n: [d0, d1, d0],
            uv: [[u0, 0.0], [u1, height], [u0, height]],
        });
        if caps {
            let top = v3(0.0, height, 0.0);
            let uv = |p: V3| [p.x, p.z];
            m.triangles
                .push(Triangle::flat([top, t0, t1], [uv(top), uv(t0), uv(t1)]));
            m.triangles.push(Triangle::flat(
                [V3::ZERO, b1, b0],
                [uv(V3::ZERO), uv(b1), uv(b0)],
            ));
        }
    }
    m
}

/// A UV sphere of `radius` at the origin with `segments` around and `segments / 2` rings.
pub fn sphere(radius: f32, segments: usize) -> Mesh {
    let segments = segments.max(4);
    let rings = (segments / 2).max(2);
    let point = |i: usize, j: usize| {
        let (theta, phi) = (
            PI * j as f32 / rings as f32,
            TAU * i as f32 / segments as f32,
        );
        v3(
            theta.sin() * phi.sin(),
            theta.cos(),
            theta.sin() * phi.cos(),
        )
    };
    let uv = |i: usize, j: usize| {
        [
            TAU * radius * i as f32 / segments as f32,
            PI * radius * (1.0 - j as f32 / rings as f32),
        ]
    };
    let mut m = Mesh::default();
    for j in 0..rings {
        for i in 0..segments {
            let (a, b, c, d) = (
                point(i, j),
                point(i, j + 1),
                point(i + 1, j + 1),
                point(i + 1, j),
            );
            if j > 0 {
                m.triangles.push(Triangle {
                    p: [a * radius, b * radius, d * radius],
                    n: [a, b, d],
                    uv: [uv(i, j), uv(i, j + 1), uv(i + 1, j)],
                });
            }
            if j + 1 < rings {
                m.triangles.push(Triangle {
                    p: [b * radius, c * radius, d * radius],
                    n: [b, c, d],
                    uv: [uv(i, j + 1), uv(i + 1, j + 1), uv(i + 1, j)],
                });
            }
        }
    }
    m
}

/// A torus around +y: ring radius `major`, tube radius `minor`.
pub fn torus(major: f32, minor: f32, segments: usize, tube_segments: usize) -> Mesh {
    let (segments, tube_segments) = (segments.max(3), tube_segments.max(3));
    let frame = |i: usize, j: usize| {
        let (a, b) = (
            TAU * i as f32 / segments as f32,
            TAU * j as f32 / tube_segments as f32,
        );
        let radial = v3(a.sin(), 0.0, a.cos());
        let n = radial * b.cos() + v3(0.0, b.sin(), 0.0);
        (radial * major + n * minor, n, [major * a, minor * b])
    };
    let mut m = Mesh::default();
    for i in 0..segments {
        for j in 0..tube_segments {
            let c = [
                frame(i, j),
                frame(i + 1, j),
                frame(i + 1, j + 1),
                frame(i, j + 1),
            ];
            m.triangles.push(Triangle {
                p: [c[0].0, c[1].0, c[2].0],
                n: [c[0].1, c[1].1, c[2].1],
                uv: [c[0].2, c[1].2, c[2].2],
            });
            m.triangles.push(Triangle {
                p: [c[0].0, c[2].0, c[3].0],
                n: [c[0].1, c[2].1, c[3].1],
                uv: [c[0].2, c[2].2, c[3].2],
            });
        }
    }
    m
}

/// A thin straight rod (a rope, a chain) of `radius` between two points.
pub fn rod(from: V3, to: V3, radius: f32, segments: usize) -> Mesh {
    let axis = to - from;
    let length = axis.length();
    let y = axis.normalized();
    // Any unit vector not parallel to the axis completes the frame.
    let helper = if y.y.abs() < 0.9 {
        v3(0.0, 1.0, 0.0)
    } else {
        v3(1.0, 0.0, 0.0)
    };
    let x = helper.cross(y).normalized();
    let z = x.cross(y);
    cylinder(radius, length, segments, false).transformed(&Transform::from_columns(x, y, z, from))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outward(mesh: &Mesh, centre: V3) -> bool {
        mesh.triangles.iter().all(|t| {
            let c = (t.p[0] + t.p[1] + t.p[2]) * (1.0 / 3.0);
            let face = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]);
            face.dot(c - centre) > 0.0 && t.n.iter().all(|n| n.dot(face) > 0.0)
        })
    }

    #[test]
    fn closed_shapes_face_outward() {
        assert!(outward(
            &cuboid(v3(-1.0, -2.0, -3.0), v3(1.0, 2.0, 3.0)),
            V3::ZERO
        ));
        assert!(outward(&sphere(2.0, 16), V3::ZERO));
        assert!(outward(&cylinder(1.0, 2.0, 12, false), v3(0.0, 1.0, 0.0)));
        assert_eq!(cuboid(V3::ZERO, V3::splat(1.0)).triangles.len(), 12);
        let r = rod(v3(1.0, 1.0, 1.0), v3(1.0, 3.0, 2.0), 0.1, 6);
        assert!(r
            .triangles
            .iter()
            .flat_map(|t| t.p)
            .all(|p| p.y > 0.9 && p.y < 3.1));
    }

    #[test]
    fn holes_are_cut_out() {
        let wall = wall_with_holes(
            V3::ZERO,
            v3(4.0, 0.0, 0.0),
            v3(0.0, 3.0, 0.0),
            &[[1.0, 1.0, 2.0, 2.0]],
        );
        let area: f32 = wall
            .triangles
            .iter()
            .map(|t| 0.5 * (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).length())
            .sum();
        assert!((area - 11.0).abs() < 1e-4, "{area}");
    }
}
