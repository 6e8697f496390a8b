//! One tile of a frame: a run of `TILE` consecutive pixels, relit by uniform passes
//! (one weight per plane, the planes streamed eight at a time) and by positional
//! lights, per block of [`BLOCK`] pixels: each light gives every pixel one light
//! vector and RGB weight (point, spot, projector) or one per emitter sample (area),
//! and [`Frame::shine`] evaluates the basis there ([`PixelBasis`]: SH's f32 recurrence
//! or the basis' weight table), dots it with the block's coefficients and adds it
//! weighted. On linear maps an area light's samples are added up on the basis first
//! (their projection, `Σ_k g_k y(l_k)` per pixel) and dotted with the coefficients once.

use super::kernels::{AreaSamples, Cone, Falloff, PixelBasis, Projector, Rows, Shift, Simd};
use super::kernels::{Stored, BLOCK};
use super::points::SurfacePoints;
use crate::color;
use crate::light::PreparedLight;
use crate::storage::{PlaneCoding, Planes};
use std::cell::RefCell;

/// Pixels per tile: each plane's segment (64 KiB in f32, 16 KiB in u8) is read in one
/// sequential run, and the three channel accumulators (192 KiB) stay in L2. A quarter
/// of that (accumulators in L1) was up to 9 % slower for uniform frames of every
/// storage at 8192×2048 and 1024×256 (more, shorter streams per plane), and no
/// different for point lights.
pub(crate) const TILE: usize = 16384;

/// A uniform pass: weights per channel and coefficient on the stored values (plane
/// scale folded in), a constant (plane bias folded in), and the RGB tint applied after
/// the sRGB decode of display-referred maps.
pub(crate) struct UniformPass {
    pub weights: [Vec<f32>; 3],
    pub offset: [f32; 3],
    pub tint: [f32; 3],
}

impl UniformPass {
    /// The pass of coefficient weights `w[c][i]` (f64) on `planes`.
    pub(crate) fn new(w: &[Vec<f64>; 3], tint: [f32; 3], planes: &Planes) -> Self {
        let mut weights: [Vec<f32>; 3] = Default::default();
        let mut offset = [0f32; 3];
        for c in 0..3 {
            let mut o = 0f64;
            weights[c] = w[c]
                .iter()
                .enumerate()
                .map(|(i, &v)| {
                    let PlaneCoding { scale, offset } = planes.coding(3 * i + c);
                    o += v * offset as f64;
                    (v * scale as f64) as f32
                })
                .collect();
            offset[c] = o as f32;
        }
        Self {
            weights,
            offset,
            tint,
        }
    }
}

/// A light with a position, in f32, its RGB scaled by the exposure.
pub(crate) enum PositionalLight {
    /// A point light, or a spot light with its cone.
    Point {
        position: [f32; 3],
        rgb: [f32; 3],
        falloff: Falloff,
        cone: Option<Cone>,
    },
    Projector(Projector),
    Area {
        samples: AreaSamples,
        rgb: [f32; 3],
    },
}

impl PositionalLight {
    /// The f32 form of a prepared positional light; `None` for uniform ones.
    pub(crate) fn new(light: &PreparedLight, scale: f64) -> Option<Self> {
        let f3 = |v: crate::sphere::Vec3| [v.x as f32, v.y as f32, v.z as f32];
        let rgb = |rgb: &[f64; 3]| rgb.map(|c| (c * scale) as f32);
        match light {
            PreparedLight::Point(l, c) => Some(Self::Point {
                position: f3(l.position),
                rgb: rgb(c),
                falloff: Falloff::of(l.attenuation),
                cone: None,
            }),
            PreparedLight::Spot(l, c) => {
                let axis = l.direction.normalized()?;
                let outer = l.cone_deg.to_radians().cos() as f32;
                let inner = (l.cone_deg - l.softness_deg).max(0.0).to_radians().cos() as f32;
                Some(Self::Point {
                    position: f3(l.position),
                    rgb: rgb(c),
                    falloff: Falloff::of(l.attenuation),
                    cone: Some(Cone {
                        axis: f3(axis),
                        outer,
                        inner,
                    }),
                })
            }
            PreparedLight::Projector(p, c) => Some(Self::Projector(Projector::new(p, rgb(c)))),
            PreparedLight::Area(l, c) => Some(Self::Area {
                samples: AreaSamples::new(l)?,
                rgb: rgb(c),
            }),
            PreparedLight::Directional { .. } | PreparedLight::Weights(_) => None,
        }
    }
}

/// Pixels whose coefficients the positional path decodes at once: each plane's run
/// (4 KiB in f32) is read sequentially, and the `3k` runs (up to 768 KiB) stay in L2.
/// Reading 64-pixel blocks straight from the `3k` planes (f32 planes used to be) was
/// 2× slower at 8192×2048 and 1.2× faster at 1024×256, k = 16 (48 short streams for
/// the prefetchers; software prefetches of the next run stalled on full fill buffers
/// and cost 25 % at both sizes): decoding wins where it matters.
const RUN: usize = 1024;

/// The groups of coefficients a uniform pass reads together, `(first, count)`: eights,
/// then a four, then ones (the kernels exist for these counts).
fn plane_groups(k: usize) -> impl Iterator<Item = (usize, usize)> + Clone {
    let eights = k / 8;
    let four = (k % 8) / 4;
    let ones = k % 4;
    (0..eights)
        .map(|g| (8 * g, 8))
        .chain((0..four).map(move |_| (8 * eights, 4)))
        .chain((0..ones).map(move |o| (8 * eights + 4 * four + o, 1)))
}

/// Per-thread buffers, reused across tiles and frames.
pub(crate) struct Scratch {
    acc: [Vec<f32>; 3],
    /// `3k` rows of [`RUN`] decoded values (frames with positional lights).
    values: Vec<f32>,
    /// `k` rows: the projection of a block's area light samples on the basis.
    projection: Vec<[f32; BLOCK]>,
    /// `k` rows: the basis at a block's light vectors (weight-table path).
    basis_rows: Vec<[f32; BLOCK]>,
}

thread_local! {
    /// Kept between frames: allocated per rayon split (`for_each_init`), the buffers
    /// were zeroed, faulted in and given back every frame (page faults, TLB shootdowns
    /// and memset were 8 % of the samples of 1024×256 directional frames under `perf`;
    /// the frame-time difference stayed within this machine's noise).
    static SCRATCH: RefCell<Scratch> = const {
        RefCell::new(Scratch {
            acc: [Vec::new(), Vec::new(), Vec::new()],
            values: Vec::new(),
            projection: Vec::new(),
            basis_rows: Vec::new(),
        })
    };
}

impl Scratch {
    /// Run `f` with this thread's buffers, sized for `k` coefficients (the value rows
    /// only for frames with positional lights).
    pub(crate) fn with<R>(k: usize, positional: bool, f: impl FnOnce(&mut Scratch) -> R) -> R {
        let fit = |s: &mut Scratch| {
            for a in &mut s.acc {
                a.resize(TILE, 0.0);
            }
            if positional {
                s.values.resize(3 * k * RUN, 0.0);
                s.projection.resize(k, [0.0; BLOCK]);
                s.basis_rows.resize(k, [0.0; BLOCK]);
            }
        };
        SCRATCH.with(|cell| match cell.try_borrow_mut() {
            Ok(mut s) => {
                fit(&mut s);
                f(&mut s)
            }
            // Not reached (tiles start no nested work), but a fresh set is correct.
            Err(_) => {
                let mut s = Scratch {
                    acc: Default::default(),
                    values: Vec::new(),
                    projection: Vec::new(),
                    basis_rows: Vec::new(),
                };
                fit(&mut s);
                f(&mut s)
            }
        })
    }
}

/// Everything a frame's tiles share.
pub(crate) struct Frame<'a> {
    pub simd: Simd,
    pub planes: &'a Planes<'a>,
    /// Pixels per plane.
    pub n: usize,
    pub k: usize,
    pub display: bool,
    pub passes: &'a [UniformPass],
    pub lights: &'a [PositionalLight],
    /// Surface points (NaN where nothing was hit), when `lights` is not empty.
    pub points: Option<&'a SurfacePoints<'a>>,
    /// The basis per pixel, when `lights` is not empty.
    pub basis: Option<&'a PixelBasis>,
    /// Write the frame with non-temporal stores (one uniform pass, nothing added after
    /// it, a frame larger than the caches).
    pub stream: bool,
}

impl Frame<'_> {
    /// Relight pixels `p0 .. p0 + dst.len() / 3` into `dst` (interleaved RGB),
    /// overwriting it.
    pub(crate) fn tile(&self, p0: usize, dst: &mut [f32], scratch: &mut Scratch) {
        match self.planes {
            Planes::F32(d) => self.tile_typed(d, p0, dst, scratch),
            Planes::F16(d) => self.tile_typed(d, p0, dst, scratch),
            Planes::U8 { data, .. } => self.tile_typed(data, p0, dst, scratch),
        }
    }

    fn tile_typed<T: Stored>(&self, data: &[T], p0: usize, dst: &mut [f32], scratch: &mut Scratch) {
        let len = dst.len() / 3;
        let n = self.n;
        if self.passes.is_empty() {
            dst.fill(0.0);
        }
        let k = self.k;
        let plane = |j: usize| &data[j * n + p0..j * n + p0 + len];
        // Groups of planes read together (channel, first coefficient, count): the first
        // of a channel writes its accumulator (from the pass's constant), the others add
        // to it; eight planes a group halve the accumulator's trips through L1.
        let groups = (0..3).flat_map(|c| plane_groups(k).map(move |(i, m)| (c, i, m)));
        for (index, pass) in self.passes.iter().enumerate() {
            for (c, i, m) in groups.clone() {
                let acc = &mut scratch.acc[c][..len];
                let w = &pass.weights[c];
                let seg = |d: usize| plane(3 * (i + d) + c);
                let offset = pass.offset[c];
                let first = i == 0;
                match m {
                    8 => {
                        let planes = std::array::from_fn::<_, 8, _>(seg);
                        let w = std::array::from_fn(|d| w[i + d]);
                        if first {
                            self.simd.axpy_init(acc, planes, w, offset);
                        } else {
                            self.simd.axpy(acc, planes, w);
                        }
                    }
                    4 => {
                        let planes = std::array::from_fn::<_, 4, _>(seg);
                        let w = std::array::from_fn(|d| w[i + d]);
                        if first {
                            self.simd.axpy_init(acc, planes, w, offset);
                        } else {
                            self.simd.axpy(acc, planes, w);
                        }
                    }
                    _ if first => self.simd.axpy_init(acc, [seg(0)], [w[i]], offset),
                    _ => self.simd.axpy(acc, [seg(0)], [w[i]]),
                }
                if i + m < k {
                    continue;
                }
                let acc = &mut scratch.acc[c][..len];
                if self.display {
                    for v in acc.iter_mut() {
                        *v = pass.tint[c] * color::srgb_to_linear(v.clamp(0.0, 1.0));
                    }
                } else if pass.tint[c] != 1.0 {
                    acc.iter_mut().for_each(|v| *v *= pass.tint[c]);
                }
            }
            let [r, g, b] = &scratch.acc;
            if index == 0 && self.stream {
                self.simd
                    .interleave_stream(dst, [&r[..len], &g[..len], &b[..len]]);
            } else if index == 0 {
                self.simd.interleave(dst, [&r[..len], &g[..len], &b[..len]]);
            } else {
                for (p, px) in dst.chunks_exact_mut(3).enumerate() {
                    px[0] += r[p];
                    px[1] += g[p];
                    px[2] += b[p];
                }
            }
        }
        let (Some(points), Some(basis)) = (self.points, self.basis) else {
            return;
        };
        if self.lights.is_empty() {
            return;
        }
        // Every plane's run is decoded (f32: copied) into the scratch rows, one
        // sequential read each, and the blocks read their values there, in L2.
        let Scratch {
            values: scratch_values,
            projection,
            basis_rows,
            ..
        } = scratch;
        let mut block = Block {
            basis,
            projection,
            rows: basis_rows,
        };
        for r0 in (0..len).step_by(RUN) {
            let rl = RUN.min(len - r0);
            for (j, row) in scratch_values.chunks_exact_mut(RUN).enumerate() {
                let PlaneCoding { scale, offset } = self.planes.coding(j);
                let at = j * n + p0 + r0;
                self.simd
                    .decode(&mut row[..rl], &data[at..at + rl], scale, offset);
                row[rl..].fill(0.0);
            }
            for b in (0..rl).step_by(BLOCK) {
                let values = Rows {
                    data: scratch_values,
                    stride: RUN,
                    offset: b,
                };
                let bl = BLOCK.min(rl - b);
                self.positional_block(p0 + r0 + b, r0 + b, bl, values, points, &mut block, dst);
            }
        }
    }

    /// Add the positional lights over pixels `q0 .. q0 + bl` (`b0` within the tile).
    #[allow(clippy::too_many_arguments)]
    fn positional_block(
        &self,
        q0: usize,
        b0: usize,
        bl: usize,
        values: Rows,
        points: &SurfacePoints,
        block: &mut Block,
        dst: &mut [f32],
    ) {
        let mut at = [[f32::NAN; BLOCK]; 3];
        points.fill(self.simd, q0, bl, &mut at);
        let mut dir = [[0f32; BLOCK]; 3];
        let mut weight = [[0f32; BLOCK]; 3];
        let mut sum = [[0f32; BLOCK]; 3];
        for light in self.lights {
            match light {
                PositionalLight::Point {
                    position,
                    rgb,
                    falloff,
                    cone,
                } => {
                    let mut factor = [0f32; BLOCK];
                    self.simd
                        .light_block(*position, *falloff, *cone, &at, &mut dir, &mut factor);
                    if factor == [0.0; BLOCK] {
                        continue;
                    }
                    for (w, c) in weight.iter_mut().zip(rgb) {
                        for (w, f) in w.iter_mut().zip(&factor) {
                            *w = c * f;
                        }
                    }
                    self.shine(block, &dir, &weight, values, &mut sum);
                }
                PositionalLight::Projector(p) => {
                    self.simd.projector_block(p, &at, &mut dir, &mut weight);
                    if weight == [[0.0; BLOCK]; 3] {
                        continue;
                    }
                    self.shine(block, &dir, &weight, values, &mut sum);
                }
                PositionalLight::Area { samples, rgb } => {
                    self.area(block, samples, *rgb, q0, &at, values, &mut sum)
                }
            }
        }
        for (p, px) in dst[3 * b0..3 * (b0 + bl)].chunks_exact_mut(3).enumerate() {
            px[0] += sum[0][p];
            px[1] += sum[1][p];
            px[2] += sum[2][p];
        }
    }

    /// Add one light vector per pixel, `dir`, of RGB weight `weight` to the block's
    /// `sum`: the basis there dotted with the coefficients (decoded to linear for
    /// display-referred maps), times the weight.
    fn shine(
        &self,
        block: &mut Block,
        dir: &[[f32; BLOCK]; 3],
        weight: &[[f32; BLOCK]; 3],
        values: Rows,
        sum: &mut [[f32; BLOCK]; 3],
    ) {
        let mut dot = [[0f32; BLOCK]; 3];
        block
            .basis
            .dot(self.simd, dir, values, &mut dot, block.rows);
        self.simd.add_weighted(self.display, &dot, weight, sum);
    }

    /// Add an area light's samples to the block's `sum` (pixels `q0 ..`, surface
    /// points `at`).
    #[allow(clippy::too_many_arguments)]
    fn area(
        &self,
        block: &mut Block,
        light: &AreaSamples,
        rgb: [f32; 3],
        q0: usize,
        at: &[[f32; BLOCK]; 3],
        values: Rows,
        sum: &mut [[f32; BLOCK]; 3],
    ) {
        let mut shift = Shift::new();
        shift.fill(light, q0);
        let mut dir = [[0f32; BLOCK]; 3];
        let mut g = [0f32; BLOCK];
        // Display-referred maps decode every sample's value: one dot per sample. On
        // linear maps the samples are summed on the basis first (`k` multiply-adds into
        // the projection per sample instead of the dot's `3k` with the coefficients):
        // 2.0–2.5× faster for 16 samples at 1024×256, k = 16 and 25, f32 and u8 (SH).
        if self.display {
            let mut weight = [[0f32; BLOCK]; 3];
            for k in 0..light.samples {
                self.simd
                    .area_sample(light, k, &shift, at, &mut dir, &mut g);
                if g == [0.0; BLOCK] {
                    continue;
                }
                for (w, c) in weight.iter_mut().zip(rgb) {
                    for (w, g) in w.iter_mut().zip(&g) {
                        *w = c * g;
                    }
                }
                self.shine(block, &dir, &weight, values, sum);
            }
            return;
        }
        let projection = &mut block.projection[..self.k];
        projection.fill([0.0; BLOCK]);
        let mut total = [0f32; BLOCK];
        for k in 0..light.samples {
            self.simd
                .area_sample(light, k, &shift, at, &mut dir, &mut g);
            if g == [0.0; BLOCK] {
                continue;
            }
            block.basis.project(self.simd, &dir, &g, projection);
            for (t, g) in total.iter_mut().zip(&g) {
                *t += g;
            }
        }
        if total == [0.0; BLOCK] {
            return;
        }
        // Weights are positive: a pixel some sample reached has a positive total.
        let weight = rgb.map(|c| total.map(|t| if t > 0.0 { c } else { 0.0 }));
        let mut dot = [[0f32; BLOCK]; 3];
        self.simd.rows_dot(projection, values, &mut dot);
        self.simd.add_weighted(false, &dot, &weight, sum);
    }
}

/// What the positional lights of one tile work with besides the coefficients: the basis
/// per pixel and its scratch rows.
struct Block<'s> {
    basis: &'s PixelBasis,
    /// `k` rows: the projection of an area light's samples.
    projection: &'s mut [[f32; BLOCK]],
    /// `k` rows: the basis at the light vectors (weight-table path).
    rows: &'s mut [[f32; BLOCK]],
}
