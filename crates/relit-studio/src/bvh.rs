//! A bounding-volume hierarchy over triangles: binned SAH build, stack traversal.
//!
//! The build sorts triangle indices in place, choosing at each node the split among
//! [`BINS`] buckets per axis that minimises the surface-area heuristic; a node whose
//! best split costs more than keeping it whole becomes a leaf. Binning makes the
//! build O(n log n) with a small constant: a million triangles build in about a
//! second on one core. The two halves of large nodes build in parallel (rayon).
//!
//! Traversal visits the nearer child first (by the sign of the ray direction on the
//! node's split axis) and, for shadow rays, stops at the first blocking hit.

use crate::math::{v3, V3};

/// Buckets per axis of the binned SAH; 16 is the usual sweet spot (more bins barely
/// improve the tree and slow the build).
const BINS: usize = 16;
/// Most triangles a leaf may hold.
const MAX_LEAF: usize = 8;
/// Cost of visiting a node relative to one triangle test (SAH traversal constant).
const TRAVERSAL_COST: f32 = 1.0;
/// Nodes with more triangles than this build their children in parallel.
const PARALLEL_THRESHOLD: usize = 32 * 1024;
/// Traversal stack depth; the build caps the tree depth below it.
const STACK: usize = 64;
const MAX_DEPTH: usize = STACK - 2;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: V3,
    pub max: V3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: V3::splat(f32::INFINITY),
        max: V3::splat(f32::NEG_INFINITY),
    };

    pub fn grow(&mut self, p: V3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }
    pub fn extent(&self) -> V3 {
        (self.max - self.min).max(V3::ZERO)
    }
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }
    pub fn centre(&self) -> V3 {
        (self.min + self.max) * 0.5
    }
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }
}

/// A ray prepared for traversal: origin, unit direction and reciprocal direction.
#[derive(Clone, Copy, Debug)]
pub struct TraceRay {
    pub origin: V3,
    pub direction: V3,
    inv: V3,
}

impl TraceRay {
    pub fn new(origin: V3, direction: V3) -> TraceRay {
        // A zero component gives ±∞, which the slab test handles; a huge finite stand-in
        // would be needed only for 0·∞ = NaN, avoided by the min/max order below.
        let inv = v3(1.0 / direction.x, 1.0 / direction.y, 1.0 / direction.z);
        TraceRay {
            origin,
            direction,
            inv,
        }
    }

    /// Entry distance into `b` if the ray meets it within `(0, t_max)`, else ∞.
    #[inline]
    fn slab(&self, b: &Node, t_max: f32) -> f32 {
        let tx1 = (b.min.x - self.origin.x) * self.inv.x;
        let tx2 = (b.max.x - self.origin.x) * self.inv.x;
        let ty1 = (b.min.y - self.origin.y) * self.inv.y;
        let ty2 = (b.max.y - self.origin.y) * self.inv.y;
        let tz1 = (b.min.z - self.origin.z) * self.inv.z;
        let tz2 = (b.max.z - self.origin.z) * self.inv.z;
        // f32::min/max return the other operand for NaN (origin on a slab with a zero
        // direction component), which keeps such rays conservative.
        let t_near = tx1.min(tx2).max(ty1.min(ty2)).max(tz1.min(tz2)).max(0.0);
        let t_far = tx1.max(tx2).min(ty1.max(ty2)).min(tz1.max(tz2)).min(t_max);
        if t_near <= t_far {
            t_near
        } else {
            f32::INFINITY
        }
    }
}

/// The nearest hit: distance, triangle index (as given to [`Bvh::build`]) and the
/// barycentric coordinates of vertices 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub triangle: u32,
    pub u: f32,
    pub v: f32,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    min: V3,
    max: V3,
    /// Leaf: index of its first triangle in `order`. Interior: index of the second
    /// child (the first child follows the node).
    offset: u32,
    /// Triangles in a leaf; 0 for an interior node.
    count: u32,
    /// Split axis of an interior node.
    axis: u32,
}

/// Precomputed triangle for Möller–Trumbore: a vertex and two edges.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v0: V3,
    e1: V3,
    e2: V3,
}

/// The hierarchy and a copy of the triangles in leaf order.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
    /// Original index of each triangle in leaf order.
    order: Vec<u32>,
}

struct BuildItem {
    bounds: Aabb,
    centre: V3,
    index: u32,
}

impl Bvh {
    /// Build over `triangles` (three vertices each). Degenerate and non-finite
    /// triangles are kept out of the tree, so they are never hit.
    pub fn build(triangles: &[[V3; 3]]) -> Bvh {
        let mut items: Vec<BuildItem> = triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                t.iter().all(|p| p.is_finite()) && (t[1] - t[0]).cross(t[2] - t[0]).length() > 0.0
            })
            .map(|(i, t)| {
                let mut bounds = Aabb::EMPTY;
                t.iter().for_each(|&p| bounds.grow(p));
                BuildItem {
                    bounds,
                    centre: bounds.centre(),
                    index: i as u32,
                }
            })
            .collect();
        let nodes = if items.is_empty() {
            vec![Node {
                min: V3::ZERO,
                max: V3::ZERO,
                offset: 0,
                count: 0,
                axis: 0,
            }]
        } else {
            build_node(&mut items, 0, 0)
        };
        let order: Vec<u32> = items.iter().map(|it| it.index).collect();
        let tris = order
            .iter()
            .map(|&i| {
                let [a, b, c] = triangles[i as usize];
                Tri {
                    v0: a,
                    e1: b - a,
                    e2: c - a,
                }
            })
            .collect();
        Bvh { nodes, tris, order }
    }

    /// The bounds of everything in the tree.
    pub fn bounds(&self) -> Aabb {
        if self.tris.is_empty() {
            return Aabb::EMPTY;
        }
        Aabb {
            min: self.nodes[0].min,
            max: self.nodes[0].max,
        }
    }

    /// The nearest hit with `t` in `(0, t_max)`.
    pub fn intersect(&self, ray: &TraceRay, t_max: f32) -> Option<Hit> {
        if self.tris.is_empty() {
            return None;
        }
        let mut best: Option<Hit> = None;
        let mut t_max = t_max;
        let mut stack = [0u32; STACK];
        let mut top = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let start = n.offset as usize;
                for k in start..start + n.count as usize {
                    if let Some((t, u, v)) = intersect_triangle(&self.tris[k], ray, t_max) {
                        t_max = t;
                        best = Some(Hit {
                            t,
                            triangle: self.order[k],
                            u,
                            v,
                        });
                    }
                }
            } else {
                let (first, second) = self.children_in_order(node, ray);
                let t_first = ray.slab(&self.nodes[first], t_max);
                let t_second = ray.slab(&self.nodes[second], t_max);
                match (t_first.is_finite(), t_second.is_finite()) {
                    (true, true) => {
                        // Visit the nearer box first; the other waits on the stack.
                        let (near, far) = if t_first <= t_second {
                            (first, second)
                        } else {
                            (second, first)
                        };
                        stack[top] = far as u32;
                        top += 1;
                        node = near;
                        continue;
                    }
                    (true, false) => {
                        node = first;
                        continue;
                    }
                    (false, true) => {
                        node = second;
                        continue;
                    }
                    (false, false) => {}
                }
            }
            // Pop the next node whose box the ray still meets before the best hit.
            loop {
                if top == 0 {
                    return best;
                }
                top -= 1;
                let candidate = stack[top] as usize;
                if ray.slab(&self.nodes[candidate], t_max).is_finite() {
                    node = candidate;
                    break;
                }
            }
        }
    }

    /// Whether any triangle lies on the ray with `t` in `(0, t_max)` (shadow rays: the
    /// first hit found ends the search).
    pub fn occluded(&self, ray: &TraceRay, t_max: f32) -> bool {
        if self.tris.is_empty() || ray.slab(&self.nodes[0], t_max).is_infinite() {
            return false;
        }
        let mut stack = [0u32; STACK];
        let mut top = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let start = n.offset as usize;
                for k in start..start + n.count as usize {
                    if intersect_triangle(&self.tris[k], ray, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                let (first, second) = self.children_in_order(node, ray);
                let hit_first = ray.slab(&self.nodes[first], t_max).is_finite();
                let hit_second = ray.slab(&self.nodes[second], t_max).is_finite();
                if hit_first {
                    if hit_second {
                        stack[top] = second as u32;
                        top += 1;
                    }
                    node = first;
                    continue;
                }
                if hit_second {
                    node = second;
                    continue;
                }
            }
            if top == 0 {
                return false;
            }
            top -= 1;
            node = stack[top] as usize;
        }
    }

    /// The children of interior node `node`, the one on the ray's near side of the
    /// split axis first.
    #[inline]
    fn children_in_order(&self, node: usize, ray: &TraceRay) -> (usize, usize) {
        let n = &self.nodes[node];
        let (left, right) = (node + 1, n.offset as usize);
        if ray.direction.axis(n.axis as usize) < 0.0 {
            (right, left)
        } else {
            (left, right)
        }
    }

    /// The number of triangles in the tree.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }
}

/// Möller–Trumbore: `(t, u, v)` when the ray meets the triangle with `t` in `(0, t_max)`.
#[inline]
fn intersect_triangle(tri: &Tri, ray: &TraceRay, t_max: f32) -> Option<(f32, f32, f32)> {
    let p = ray.direction.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-20 {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - tri.v0;
    let u = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = ray.direction.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = tri.e2.dot(q) * inv_det;
    (t > 0.0 && t < t_max).then_some((t, u, v))
}

/// Build the subtree over `items` (reordered in place); node offsets are relative to
/// the returned vector's start and leaf offsets to `first` (the items' global start).
fn build_node(items: &mut [BuildItem], first: usize, depth: usize) -> Vec<Node> {
    let mut bounds = Aabb::EMPTY;
    let mut centres = Aabb::EMPTY;
    for it in items.iter() {
        bounds = bounds.union(it.bounds);
        centres.grow(it.centre);
    }
    let leaf = |first: usize, count: usize| Node {
        min: bounds.min,
        max: bounds.max,
        offset: first as u32,
        count: count as u32,
        axis: 0,
    };
    let n = items.len();
    if n <= 2 || depth >= MAX_DEPTH {
        return vec![leaf(first, n)];
    }
    let Some((axis, split)) = best_split(items, &bounds, &centres) else {
        return vec![leaf(first, n)];
    };
    let mid = partition(items, |it| {
        bin_of(it.centre.axis(axis), &centres, axis) < split
    });
    // Binning can put everything on one side when centres coincide in a bin; fall back
    // to a median split so the build always progresses.
    let mid = if mid == 0 || mid == n {
        items.sort_unstable_by(|a, b| a.centre.axis(axis).total_cmp(&b.centre.axis(axis)));
        n / 2
    } else {
        mid
    };
    let (left_items, right_items) = items.split_at_mut(mid);
    let (left, right) = if n > PARALLEL_THRESHOLD {
        rayon::join(
            || build_node(left_items, first, depth + 1),
            || build_node(right_items, first + mid, depth + 1),
        )
    } else {
        (
            build_node(left_items, first, depth + 1),
            build_node(right_items, first + mid, depth + 1),
        )
    };
    let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
    nodes.push(Node {
        min: bounds.min,
        max: bounds.max,
        offset: 0,
        count: 0,
        axis: axis as u32,
    });
    let shift = |mut node: Node, by: usize| {
        if node.count == 0 {
            node.offset += by as u32;
        }
        node
    };
    nodes.extend(left.into_iter().map(|nd| shift(nd, 1)));
    let right_start = nodes.len();
    nodes[0].offset = right_start as u32;
    nodes.extend(right.into_iter().map(|nd| shift(nd, right_start)));
    nodes
}

fn bin_of(c: f32, centres: &Aabb, axis: usize) -> usize {
    let lo = centres.min.axis(axis);
    let extent = centres.max.axis(axis) - lo;
    (((c - lo) / extent * BINS as f32) as usize).min(BINS - 1)
}

/// The axis and first right-hand bin of the cheapest SAH split, or `None` when keeping
/// the node whole as a leaf is cheaper (and allowed).
fn best_split(items: &[BuildItem], bounds: &Aabb, centres: &Aabb) -> Option<(usize, usize)> {
    let n = items.len();
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if centres.max.axis(axis) - centres.min.axis(axis) <= 0.0 {
            continue;
        }
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for it in items {
            let b = bin_of(it.centre.axis(axis), centres, axis);
            bin_bounds[b] = bin_bounds[b].union(it.bounds);
            bin_counts[b] += 1;
        }
        // Sweep from the right to get the area and count of every right-hand side.
        let mut right_area = [0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(bin_bounds[b]);
            cnt += bin_counts[b];
            right_area[b] = if acc.is_empty() { 0.0 } else { acc.half_area() };
            right_count[b] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for split in 1..BINS {
            acc = acc.union(bin_bounds[split - 1]);
            cnt += bin_counts[split - 1];
            if cnt == 0 || right_count[split] == 0 {
                continue;
            }
            let cost = cnt as f32 * acc.half_area() + right_count[split] as f32 * right_area[split];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (cost, axis, split) = best?;
    let area = bounds.half_area().max(f32::MIN_POSITIVE);
    let split_cost = TRAVERSAL_COST + cost / area;
    (split_cost < n as f32 || n > MAX_LEAF).then_some((axis, split))
}

/// Move the items satisfying `left` to the front; returns how many there are.
fn partition(items: &mut [BuildItem], left: impl Fn(&BuildItem) -> bool) -> usize {
    let mut i = 0;
    for j in 0..items.len() {
        if left(&items[j]) {
            items.swap(i, j);
            i += 1;
        }
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic soup of small triangles in a 10-unit cube.
    fn soup(n: usize) -> Vec<[V3; 3]> {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| {
                let c = v3(next() * 10.0, next() * 10.0, next() * 10.0);
                [
                    c,
                    c + v3(next() - 0.5, next() - 0.5, next() - 0.5),
                    c + v3(next() - 0.5, next() - 0.5, next() - 0.5),
                ]
            })
            .collect()
    }

    fn brute_force(tris: &[[V3; 3]], ray: &TraceRay) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for (i, t) in tris.iter().enumerate() {
            let tri = Tri {
                v0: t[0],
                e1: t[1] - t[0],
                e2: t[2] - t[0],
            };
            if let Some((d, _, _)) =
                intersect_triangle(&tri, ray, best.map_or(f32::INFINITY, |b| b.0))
            {
                best = Some((d, i as u32));
            }
        }
        best
    }

    #[test]
    fn bvh_agrees_with_brute_force() {
        let tris = soup(3000);
        let bvh = Bvh::build(&tris);
        assert_eq!(bvh.triangle_count(), 3000);
        for k in 0..400 {
            let f = k as f32;
            let origin = v3(-2.0 + (f * 0.37) % 14.0, (f * 0.71) % 10.0, -3.0);
            let direction = v3((f * 0.13).sin() * 0.3, (f * 0.29).cos() * 0.3, 1.0).normalized();
            let ray = TraceRay::new(origin, direction);
            let expected = brute_force(&tris, &ray);
            let got = bvh
                .intersect(&ray, f32::INFINITY)
                .map(|h| (h.t, h.triangle));
            assert_eq!(got, expected, "ray {k}");
            assert_eq!(bvh.occluded(&ray, f32::INFINITY), expected.is_some());
            if let Some((t, _)) = expected {
                assert!(
                    !bvh.occluded(&ray, t * 0.999),
                    "ray {k}: nothing before the nearest hit"
                );
                assert!(bvh.occluded(&ray, t * 1.001));
            }
        }
    }

    #[test]
    fn degenerate_input_is_skipped() {
        let p = v3(0.0, 0.0, 0.0);
        let tris = vec![
            [p, p, p],
            [p, v3(1.0, 0.0, 0.0), v3(f32::NAN, 1.0, 0.0)],
            [v3(-1.0, -1.0, 1.0), v3(1.0, -1.0, 1.0), v3(0.0, 1.0, 1.0)],
        ];
        let bvh = Bvh::build(&tris);
        assert_eq!(bvh.triangle_count(), 1);
        let hit = bvh
            .intersect(&TraceRay::new(V3::ZERO, v3(0.0, 0.0, 1.0)), f32::INFINITY)
            .unwrap();
        assert_eq!(hit.triangle, 2);
        assert!((hit.t - 1.0).abs() < 1e-6);
        let empty = Bvh::build(&[]);
        assert!(empty
            .intersect(&TraceRay::new(V3::ZERO, v3(0.0, 0.0, 1.0)), 1.0)
            .is_none());
        // Many triangles with one centre (SAH cannot split them) still build and trace.
        let stacked: Vec<[V3; 3]> = (0..100)
            .map(|i| {
                [
                    v3(-1.0, -1.0, i as f32 * 0.0),
                    v3(1.0, -1.0, 0.0),
                    v3(0.0, 1.0, 0.0),
                ]
            })
            .collect();
        let bvh = Bvh::build(&stacked);
        assert!(bvh.occluded(&TraceRay::new(v3(0.0, 0.0, -1.0), v3(0.0, 0.0, 1.0)), 5.0));
    }
}
