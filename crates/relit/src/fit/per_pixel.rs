//! The perceptual objective's per-pixel solve: each pixel's own weighted normal
//! equations, reweighted from its prediction ([`super::FitOptions::reweights`]).
//!
//! A piece of the spill file is solved a chunk of [`CHUNK`] pixels at a time, in lane
//! groups of [`LANES`] pixels whose systems are formed, factored and solved side by side
//! ([`linalg::lane_products`], [`linalg::cholesky_lanes`]); a photograph's codes are
//! looked up once a table ([`CodeTables`]).

use super::spill::Piece;
use super::{
    packed_pairs, perceptual_weight, perceptual_weight_encoded, srgb_extended, srgb_extended_batch,
    Design, SpillReader, CHUNK, DEFINITENESS, TANGENT_BELOW,
};
use crate::linalg::{self, Lanes, LanesF32, LANES};
use crate::progress::Progress;
use crate::Result;
use rayon::prelude::*;

/// Scratch space of one per-pixel solve task.
///
/// A chunk's pixels are laid out in lane groups of [`LANES`] (pixel `p` is lane
/// `p % LANES` of group `p / LANES`), light by light within a group: the layout the
/// lane kernels read ([`linalg::lane_products`], [`linalg::cholesky_lanes`]), so that
/// no system is gathered from pixel-major rows. Lanes past the chunk's last pixel hold
/// zeros and weigh nothing.
struct Scratch {
    /// The chunk's observations: per channel, per group, per light, the lanes.
    obs: Vec<Lanes>,
    /// `srgb_extended` of each observation, laid out as `obs`.
    encoded: Vec<Lanes>,
    /// `perceptual_weight` of each observation, laid out as `obs`.
    slopes: Vec<Lanes>,
    /// Each sample's weight: per group, per light, the lanes (one channel's block).
    weights: Vec<LanesF32>,
    /// The reweighted pass's weights as they are summed over the channels, laid out as
    /// `weights`.
    shared: Vec<Lanes>,
    /// A lane group's weighted observations, light by light.
    weighted_obs: Vec<LanesF32>,
    /// A lane group's normal matrix sums (the packed pairs, padded to a tile).
    sums: Vec<LanesF32>,
    /// A lane group's right-hand sides of two channels (k, padded to a tile).
    rhs: [Vec<LanesF32>; 2],
    /// Coefficients: per channel, per group, per coefficient, the lanes.
    coef: Vec<Lanes>,
    /// One channel's predictions and their `srgb_extended`, laid out as `weights`.
    pred: Vec<Lanes>,
    pred_encoded: Vec<Lanes>,
    /// A lane group's predictions, padded to a tile.
    pred_tile: Vec<Lanes>,
    m: Vec<f64>,
    fallback: Vec<f64>,
    lane_m: Vec<Lanes>,
    lane_coef: Vec<Lanes>,
    lane_coef2: Vec<Lanes>,
}

impl Scratch {
    /// For chunks of at most [`CHUNK`] pixels of `n` samples and `k` coefficients.
    fn new(n: usize, k: usize) -> Scratch {
        let t = k * (k + 1) / 2;
        let groups = CHUNK.div_ceil(LANES);
        Scratch {
            obs: vec![[0.0; LANES]; 3 * groups * n],
            encoded: vec![[0.0; LANES]; 3 * groups * n],
            slopes: vec![[0.0; LANES]; 3 * groups * n],
            weights: vec![[0.0; LANES]; groups * n],
            shared: vec![[0.0; LANES]; groups * n],
            weighted_obs: vec![[0.0; LANES]; n],
            sums: vec![[0.0; LANES]; linalg::tiled(t)],
            rhs: [
                vec![[0.0; LANES]; linalg::tiled(k)],
                vec![[0.0; LANES]; linalg::tiled(k)],
            ],
            coef: vec![[0.0; LANES]; 3 * groups * k],
            pred: vec![[0.0; LANES]; groups * n],
            pred_encoded: vec![[0.0; LANES]; groups * n],
            pred_tile: vec![[0.0; LANES]; linalg::tiled(n)],
            m: vec![0.0; k * k],
            fallback: vec![0.0; k],
            lane_m: vec![[0.0; LANES]; k * k],
            lane_coef: vec![[0.0; LANES]; k],
            lane_coef2: vec![[0.0; LANES]; k],
        }
    }

    /// The observations of a chunk of `len` pixels from `sample(j, p, c)`, the lanes
    /// past the last pixel zero.
    fn fill(&mut self, n: usize, len: usize, mut sample: impl FnMut(usize, usize, usize) -> f64) {
        let groups = len.div_ceil(LANES);
        for c in 0..3 {
            for g in 0..groups {
                let used = LANES.min(len - g * LANES);
                for (j, lanes) in self.obs[(c * groups + g) * n..][..n].iter_mut().enumerate() {
                    for (l, v) in lanes.iter_mut().enumerate() {
                        *v = if l < used {
                            sample(j, g * LANES + l, c)
                        } else {
                            0.0
                        };
                    }
                }
            }
        }
    }
}

/// What each code of a file of codes stands for in the per-pixel solve: its value, the
/// value's `srgb_extended` and its `perceptual_weight`, each computed once a table
/// rather than once a sample (the images of a capture mostly share one table).
struct CodeTables {
    /// Distinct tables, `256·channel + code` each.
    tables: Vec<Vec<CodeValue>>,
    /// Each image's table.
    of_image: Vec<usize>,
}

#[derive(Clone, Copy)]
struct CodeValue {
    value: f64,
    encoded: f64,
    slope: f64,
}

impl CodeTables {
    /// From each image's values of its codes (`SpillReader::values`).
    fn new(values: &[Vec<f32>]) -> CodeTables {
        let mut distinct: Vec<&[f32]> = Vec::new();
        let mut of_image = Vec::with_capacity(values.len());
        for v in values {
            let same = |d: &&[f32]| {
                d.iter()
                    .zip(v.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            };
            let at = match distinct.iter().position(|d| d.len() == v.len() && same(d)) {
                Some(at) => at,
                None => {
                    distinct.push(v);
                    distinct.len() - 1
                }
            };
            of_image.push(at);
        }
        let tables = distinct
            .iter()
            .map(|values| {
                values
                    .iter()
                    .map(|&v| {
                        let value = v as f64;
                        let encoded = srgb_extended(value);
                        CodeValue {
                            value,
                            encoded,
                            slope: perceptual_weight_encoded(value, encoded),
                        }
                    })
                    .collect()
            })
            .collect();
        CodeTables { tables, of_image }
    }

    /// Pixels `a..a + len` of a piece of `count` pixels' codes (`[image][pixel][channel]`)
    /// into the scratch's observations, their encodings and weights, as `solve_chunk`
    /// computes them from the values.
    fn look_up(&self, codes: &[u8], count: usize, a: usize, len: usize, s: &mut Scratch) {
        let n = self.of_image.len();
        let groups = len.div_ceil(LANES);
        let zero = CodeValue {
            value: 0.0,
            encoded: 0.0,
            slope: 0.0,
        };
        for (j, &t) in self.of_image.iter().enumerate() {
            let table: &[CodeValue; 768] = self.tables[t]
                .as_slice()
                .try_into()
                .expect("a table has 256 values a channel");
            let row = &codes[(j * count + a) * 3..(j * count + a + len) * 3];
            for g in 0..groups {
                let pixels = &row[g * LANES * 3..((g + 1) * LANES * 3).min(row.len())];
                for c in 0..3 {
                    let x = (c * groups + g) * n + j;
                    let (obs, encoded, slopes) =
                        (&mut s.obs[x], &mut s.encoded[x], &mut s.slopes[x]);
                    let channel: &[CodeValue; 256] =
                        table[256 * c..][..256].try_into().expect("256 codes");
                    // A whole group (every group but a chunk's last) reads without a
                    // check per lane; the last one's lanes past its pixels are zero.
                    let whole = <&[u8; 3 * LANES]>::try_from(pixels).ok();
                    for l in 0..LANES {
                        let v = match whole {
                            Some(whole) => channel[whole[3 * l + c] as usize],
                            None => pixels
                                .get(3 * l + c)
                                .map_or(zero, |&code| channel[code as usize]),
                        };
                        (obs[l], encoded[l], slopes[l]) = (v.value, v.encoded, v.slope);
                    }
                }
            }
        }
    }
}

/// Where a solved piece goes: the piece, then runs of pixel-major coefficients.
type SolvedSink<'a> = dyn FnMut(Piece, &[Vec<f32>]) -> Result<()> + 'a;

/// Per-pixel weighted fit of every piece in the spill file; each piece's coefficients
/// go to `emit` (the piece, then runs of pixel-major coefficients).
pub(super) fn solve_per_pixel(
    reader: &SpillReader,
    design: &Design,
    lambda: f64,
    reweights: usize,
    progress: &dyn Progress,
    emit: &mut SolvedSink,
) -> Result<()> {
    let (k, n) = (design.k, design.n);
    let pairs = packed_pairs(k);
    let t = pairs.len();
    // N×T table of the outer products B_j B_jᵀ (upper triangle), so that the weighted
    // normal matrices of a chunk of pixels are one matrix product W · outer.
    // Single precision: the products sum N positive terms, so their relative error stays
    // near 1e-7; the factorisation that follows is done in double precision.
    // Both tables' rows padded to whole tiles of `linalg::lane_products` with zeros.
    let (t_cols, k_cols) = (linalg::tiled(t), linalg::tiled(k));
    let mut outer = vec![0f32; n * t_cols];
    let mut a32 = vec![0f32; n * k_cols];
    for j in 0..n {
        let row = design.row(j);
        for (x, &(r, c)) in pairs.iter().enumerate() {
            outer[j * t_cols + x] = (row[r] * row[c]) as f32;
        }
        for (dst, &v) in a32[j * k_cols..].iter_mut().zip(row) {
            *dst = v as f32;
        }
    }
    let n_cols = linalg::tiled(n);
    let mut a_t = vec![0f64; k * n_cols];
    for j in 0..n {
        for (i, &v) in design.row(j).iter().enumerate() {
            a_t[i * n_cols + j] = v;
        }
    }
    let lower: Vec<usize> = pairs.iter().map(|&(r, c)| c * k + r).collect();
    let packed_penalty: Vec<f64> = lower.iter().map(|&x| design.penalty[x]).collect();
    // A file of codes is read as its codes and looked up; a file of floats as values.
    let coded = reader.values.as_deref().map(CodeTables::new);
    progress.begin("fitting pieces", reader.pieces.len() as u64);
    let (mut buffer, mut codes) = (Vec::new(), Vec::new());
    for &piece in &reader.pieces {
        match coded {
            Some(_) => reader.spill.read_region_codes(piece, &mut codes)?,
            None => reader.read(piece, &mut buffer)?,
        }
        let count = piece.pixels();
        let (samples, codes) = (&buffer, &codes);
        let results: Vec<Vec<f32>> = (0..count.div_ceil(CHUNK))
            .into_par_iter()
            .map_init(
                || Scratch::new(n, k),
                |scratch, chunk| {
                    let a = chunk * CHUNK;
                    let len = CHUNK.min(count - a);
                    let mut out = vec![0f32; len * 3 * k];
                    let looked_up = match &coded {
                        Some(coded) => {
                            coded.look_up(codes, count, a, len, scratch);
                            true
                        }
                        None => {
                            scratch.fill(n, len, |j, p, c| {
                                samples[(j * count + a + p) * 3 + c] as f64
                            });
                            false
                        }
                    };
                    let tables = Tables {
                        design,
                        outer: &outer,
                        a32: &a32,
                        a_t: &a_t,
                        pairs: &pairs,
                        lower: &lower,
                        packed_penalty: &packed_penalty,
                        lambda,
                    };
                    solve_chunk(&tables, reweights, len, scratch, looked_up);
                    let groups = len.div_ceil(LANES);
                    for c in 0..3 {
                        for p in 0..len {
                            let (g, l) = (p / LANES, p % LANES);
                            for i in 0..k {
                                out[p * 3 * k + 3 * i + c] =
                                    scratch.coef[(c * groups + g) * k + i][l] as f32;
                            }
                        }
                    }
                    out
                },
            )
            .collect();
        emit(piece, &results)?;
        progress.advance(1);
    }
    progress.end();
    Ok(())
}

/// What every weighted solve of a fit shares.
struct Tables<'a> {
    design: &'a Design,
    /// N×T outer products of the basis rows (packed upper triangle), single precision,
    /// each row padded to whole tiles ([`linalg::tiled`]).
    outer: &'a [f32],
    /// The N×k basis values, single precision, padded as `outer`.
    a32: &'a [f32],
    /// The k×N transposed basis values, each row padded to whole tiles: the predictions.
    a_t: &'a [f64],
    pairs: &'a [(usize, usize)],
    /// Where each packed pair `(r, c)` goes in a k×k system: its lower triangle, `c·k + r`.
    lower: &'a [usize],
    /// The penalty's entry of each packed pair.
    packed_penalty: &'a [f64],
    lambda: f64,
}

/// Iteratively reweighted solve of `len` pixels' observations in `scratch.obs` into
/// `scratch.coef` (both laid out in lane groups: [`Scratch`]).
///
/// A pixel's three channels share one normal matrix and one factorisation in every
/// pass. The first pass weighs each light by the mean over the channels of their
/// observation weights; each reweighted pass by the mean over the channels of their
/// secant weights, each channel's first divided by its mean over the lights
/// ([`add_normalized`]), so that the darkest channel, whose sRGB slopes are the
/// steepest, does not alone decide the shape. Against each channel reweighted by its
/// own secants (a normal matrix and a factorisation per channel) this took 9–19 % off
/// the fit where the perceptual objective is fitted, and moved the held-out PSNR of the
/// eight shared RTI items by −0.09 … +0.05 dB (docs/bases.md, "The reweighted pass
/// shared too").
///
/// `reweights == 0` keeps each channel's own observation weights (a solve per channel).
///
/// `looked_up`: `scratch.encoded` and `scratch.slopes` already hold each observation's
/// encoding and perceptual weight ([`CodeTables::look_up`]); otherwise they are
/// computed here, the same values.
fn solve_chunk(tables: &Tables, reweights: usize, len: usize, s: &mut Scratch, looked_up: bool) {
    let (n, k, q) = (tables.design.n, tables.design.k, &tables.design.q);
    let groups = len.div_ceil(LANES);
    let block = groups * n;
    if !looked_up {
        // Every observation encoded once: its first weight and each secant read it.
        srgb_extended_batch(
            s.obs[..3 * block].as_flattened(),
            s.encoded[..3 * block].as_flattened_mut(),
        );
        let (obs, encoded) = (s.obs[..3 * block].as_flattened(), s.encoded.as_flattened());
        for ((slope, &v), &e) in s.slopes[..3 * block]
            .as_flattened_mut()
            .iter_mut()
            .zip(obs)
            .zip(encoded)
        {
            *slope = perceptual_weight_encoded(v, e);
        }
    }
    if reweights == 0 {
        for c in 0..3 {
            let slopes = s.slopes[c * block..(c + 1) * block].as_flattened();
            weigh(&mut s.weights[..block], q, |x| slopes[x]);
            weighted_solve(tables, len, c..c + 1, s);
        }
        return;
    }
    let slopes = s.slopes.as_flattened();
    let lanes_block = block * LANES;
    weigh(&mut s.weights[..block], q, |x| {
        (0..3).map(|c| slopes[c * lanes_block + x]).sum::<f64>() / 3.0
    });
    weighted_solve(tables, len, 0..3, s);
    let n_cols = tables.a_t.len() / k;
    for _ in 0..reweights {
        s.shared[..block].fill([0.0; LANES]);
        for c in 0..3 {
            for g in 0..groups {
                let coef = &s.coef[(c * groups + g) * k..(c * groups + g + 1) * k];
                linalg::lane_products_f64(coef, tables.a_t, n_cols, &mut s.pred_tile);
                s.pred[g * n..(g + 1) * n].copy_from_slice(&s.pred_tile[..n]);
            }
            srgb_extended_batch(
                s.pred[..block].as_flattened(),
                s.pred_encoded[..block].as_flattened_mut(),
            );
            let obs = &s.obs[c * block..(c + 1) * block];
            let obs_encoded = &s.encoded[c * block..(c + 1) * block];
            weigh_secants(
                &mut s.weights[..block],
                q,
                [&s.pred[..block], obs],
                [&s.pred_encoded[..block], obs_encoded],
            );
            add_normalized(&mut s.shared[..block], &s.weights[..block], n);
        }
        for (w, shared) in s.weights[..block].iter_mut().zip(&s.shared[..block]) {
            *w = shared.map(|v| v as f32);
        }
        weighted_solve(tables, len, 0..3, s);
    }
}

/// Add one channel's weights `weights` (lane groups of `n` lights) to `shared`, each lane
/// divided by its mean over the lights and by the three channels: summed over the
/// channels, a lane's weights average one. A lane whose weights are all zero adds
/// nothing.
fn add_normalized(shared: &mut [Lanes], weights: &[LanesF32], n: usize) {
    for (shared, weights) in shared.chunks_exact_mut(n).zip(weights.chunks_exact(n)) {
        let mut sum = [0.0f64; LANES];
        for w in weights {
            for l in 0..LANES {
                sum[l] += w[l] as f64;
            }
        }
        let scale: Lanes = std::array::from_fn(|l| {
            if sum[l] > 0.0 {
                n as f64 / (3.0 * sum[l])
            } else {
                0.0
            }
        });
        for (dst, w) in shared.iter_mut().zip(weights) {
            for l in 0..LANES {
                dst[l] += w[l] as f64 * scale[l];
            }
        }
    }
}

/// [`weigh`] by [`secant_weight_encoded`] of `(pred, obs)` and their encodings, bit for
/// bit: every secant first (a loop without branches, which vectorises), then the
/// tangents where the ends are too close for a secant.
fn weigh_secants(
    weights: &mut [LanesF32],
    q: &[f64],
    [pred, obs]: [&[Lanes]; 2],
    [pe, oe]: [&[Lanes]; 2],
) {
    let n = q.len();
    for (gj, w) in weights.iter_mut().enumerate() {
        let qj = q[gj % n];
        let (p, o, pe, oe) = (&pred[gj], &obs[gj], &pe[gj], &oe[gj]);
        for l in 0..LANES {
            let s = (pe[l] - oe[l]) / (p[l] - o[l]);
            w[l] = (qj * (s * s)) as f32;
        }
        for l in 0..LANES {
            if (p[l] - o[l]).abs() < TANGENT_BELOW {
                w[l] = (qj * perceptual_weight(0.5 * (p[l] + o[l]))) as f32;
            }
        }
    }
}

/// `weights[x] = q[j] · weight(x)` for sample `x` of light `j`, where `x` indexes the
/// flattened lane layout of one channel ([`Scratch`]).
#[inline]
fn weigh(weights: &mut [LanesF32], q: &[f64], weight: impl Fn(usize) -> f64) {
    let n = q.len();
    for (gj, w) in weights.iter_mut().enumerate() {
        let qj = q[gj % n];
        for (l, w) in w.iter_mut().enumerate() {
            *w = (qj * weight(gj * LANES + l)) as f32;
        }
    }
}

/// Solve the channels `channels` of `len` pixels under the weights `s.weights`, which
/// they share: one normal matrix and one factorisation per pixel, a right-hand side per
/// channel.
fn weighted_solve(tables: &Tables, len: usize, channels: std::ops::Range<usize>, s: &mut Scratch) {
    let Tables {
        design,
        outer,
        a32,
        pairs,
        lower,
        packed_penalty,
        lambda,
        ..
    } = *tables;
    let (k, n) = (design.k, design.n);
    let (t_cols, k_cols) = (outer.len() / n, a32.len() / n);
    let groups = len.div_ceil(LANES);
    // A lane group at a time (`linalg::cholesky_lanes`: each lane is the scalar solve
    // bit for bit); a lane whose system is singular is solved again alone, with the
    // larger λ of `solve_regularized`.
    for g in 0..groups {
        let used = LANES.min(len - g * LANES);
        let weights = &mut s.weights[g * n..(g + 1) * n];
        // Lanes past the last pixel weigh nothing.
        weights.iter_mut().for_each(|w| w[used..].fill(0.0));
        let mut sum = [0.0f64; LANES];
        for w in weights.iter() {
            for l in 0..LANES {
                sum[l] += w[l] as f64;
            }
        }
        let total: Lanes = std::array::from_fn(|l| if l < used { sum[l].max(1e-30) } else { 1.0 });
        linalg::lane_products(weights, outer, t_cols, &mut s.sums);
        // The lower triangle only (all that the factorisation and the solve read): the
        // weighted sums plus the penalty and the definiteness term, added in
        // `Design::regularize`'s order so that a lane is the scalar system bit for bit.
        // Unused lanes get the identity.
        let scaled: Lanes = std::array::from_fn(|l| total[l] * lambda);
        for ((&x, sums), &penalty) in lower.iter().zip(&s.sums).zip(packed_penalty) {
            s.lane_m[x] = linalg::plus_scaled(&linalg::widened(sums), &scaled, penalty);
        }
        for i in 0..k {
            for (m, &t_l) in s.lane_m[i * k + i].iter_mut().zip(&total) {
                *m += t_l * DEFINITENESS;
            }
        }
        if used < LANES {
            for (&x, &(r, c)) in lower.iter().zip(pairs) {
                s.lane_m[x][used..].fill(if r == c { 1.0 } else { 0.0 });
            }
        }
        let ok = linalg::cholesky_lanes(&mut s.lane_m, k);
        // The channels that share this factor two at a time, solved side by side
        // (`linalg::cholesky_solve_lanes_pair`, each bit for bit its own solve).
        let weights = &s.weights[g * n..(g + 1) * n];
        let mut ch = channels.start;
        while ch < channels.end {
            let both = ch + 1 < channels.end;
            for slot in 0..1 + both as usize {
                let obs = &s.obs[((ch + slot) * groups + g) * n..][..n];
                for ((wo, w), o) in s.weighted_obs.iter_mut().zip(weights).zip(obs) {
                    *wo = linalg::times_narrowed(w, o);
                }
                linalg::lane_products(&s.weighted_obs, a32, k_cols, &mut s.rhs[slot]);
                let coef = if slot == 0 {
                    &mut s.lane_coef
                } else {
                    &mut s.lane_coef2
                };
                for (c, r) in coef.iter_mut().zip(&s.rhs[slot]) {
                    *c = r.map(|v| v as f64);
                }
            }
            if both {
                linalg::cholesky_solve_lanes_pair(
                    &s.lane_m,
                    &s.lane_m,
                    k,
                    k,
                    &mut s.lane_coef,
                    &mut s.lane_coef2,
                );
            } else {
                linalg::cholesky_solve_lanes(&s.lane_m, k, &mut s.lane_coef);
            }
            for (slot, solved) in [&s.lane_coef, &s.lane_coef2]
                .into_iter()
                .enumerate()
                .take(1 + both as usize)
            {
                let coef = &mut s.coef[((ch + slot) * groups + g) * k..][..k];
                coef.copy_from_slice(solved);
                for l in (0..used).filter(|&l| !ok[l]) {
                    for (&(r, c), sums) in pairs.iter().zip(&s.sums) {
                        let v = sums[l] as f64;
                        s.m[r * k + c] = v;
                        s.m[c * k + r] = v;
                    }
                    for (dst, rhs) in s.fallback.iter_mut().zip(&s.rhs[slot]) {
                        *dst = rhs[l] as f64;
                    }
                    solve_regularized(design, &mut s.m, &mut s.fallback, lambda, total[l]);
                    for (c, &v) in coef.iter_mut().zip(&s.fallback) {
                        c[l] = v;
                    }
                }
            }
            ch += 1 + both as usize;
        }
    }
}

/// Solve `(m + λ W P) c = rhs` in place; if the system is numerically singular, retry
/// with a larger λ, and give up with zeros (a black pixel) rather than NaN.
fn solve_regularized(design: &Design, m: &mut [f64], rhs: &mut [f64], lambda: f64, total: f64) {
    let k = design.k;
    let base = m.to_vec();
    let mut l = lambda;
    for _ in 0..6 {
        m.copy_from_slice(&base);
        design.regularize(m, l, total.max(1e-30));
        if linalg::cholesky(m, k) {
            linalg::cholesky_solve(m, k, rhs);
            return;
        }
        l = (l * 100.0).max(1e-6);
    }
    rhs.iter_mut().for_each(|v| *v = 0.0);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::secant_weight_encoded;

    #[test]
    fn codes_looked_up_are_the_values_encodings_and_weights_computed_from_them() {
        // Three images over two tables, one of lights of intensity 0.6 (values above 1,
        // where the encoding is the extended line and the weight the slope at white), and
        // codes that take every value of every channel; a whole chunk and a part of one
        // whose last lane group is partly used.
        let curve: Vec<f32> = (0..768)
            .map(|x| ((x % 256) as f32 / 255.0).powf(2.2))
            .collect();
        let bright: Vec<f32> = curve.iter().map(|v| v / 0.6).collect();
        let values = vec![curve.clone(), bright, curve];
        let tables = CodeTables::new(&values);
        assert_eq!(tables.tables.len(), 2, "equal tables are kept once");
        let (n, count) = (values.len(), CHUNK + 13);
        let codes: Vec<u8> = (0..n * count * 3)
            .map(|x| ((x % 3) * 31 + (x / 3) * 7 + x / (3 * count) * 13) as u8)
            .collect();
        let mut s = Scratch::new(n, 4);
        for (a, len) in [(0, CHUNK), (CHUNK, 13)] {
            tables.look_up(&codes, count, a, len, &mut s);
            let groups = len.div_ceil(LANES);
            for (j, image) in values.iter().enumerate() {
                for c in 0..3 {
                    for g in 0..groups {
                        for l in 0..LANES {
                            let p = g * LANES + l;
                            let want = if p < len {
                                image[256 * c + codes[(j * count + a + p) * 3 + c] as usize] as f64
                            } else {
                                0.0
                            };
                            assert_eq!(s.obs[(c * groups + g) * n + j][l], want);
                        }
                    }
                }
            }
            // What `solve_chunk` computes from the values when they were not looked up.
            let block = 3 * groups * n;
            let obs = s.obs[..block].as_flattened();
            let mut want = vec![0.0; obs.len()];
            srgb_extended_batch(obs, &mut want);
            assert!(obs.iter().any(|&v| v > 1.0));
            let (encoded, slopes) = (
                s.encoded[..block].as_flattened(),
                s.slopes[..block].as_flattened(),
            );
            for x in 0..obs.len() {
                assert_eq!(encoded[x].to_bits(), want[x].to_bits(), "{}", obs[x]);
                if obs[x] != 0.0 {
                    let slope = perceptual_weight_encoded(obs[x], want[x]);
                    assert_eq!(slopes[x].to_bits(), slope.to_bits(), "{}", obs[x]);
                }
            }
        }
    }

    #[test]
    fn secants_weighed_at_once_are_each_secant_weight() {
        // Predictions far from, near (within and beyond the tangent's reach) and equal to
        // their observations, below 0 and above 1: three lights of a lane group.
        let q = [0.5, 1.0, 2.0];
        let samples = q.len() * LANES;
        let obs: Vec<f64> = (0..samples).map(|x| -0.1 + 0.06 * x as f64).collect();
        let offsets = [0.3, 4e-6, 2e-5, 0.0, -0.05, -3e-6];
        let pred: Vec<f64> = obs
            .iter()
            .enumerate()
            .map(|(x, o)| o + offsets[x % offsets.len()])
            .collect();
        let (mut pe, mut oe) = (vec![0.0; samples], vec![0.0; samples]);
        srgb_extended_batch(&pred, &mut pe);
        srgb_extended_batch(&obs, &mut oe);
        let lanes = |v: &[f64]| -> Vec<Lanes> {
            v.chunks_exact(LANES)
                .map(|c| c.try_into().unwrap())
                .collect()
        };
        let mut got = vec![[0f32; LANES]; q.len()];
        weigh_secants(
            &mut got,
            &q,
            [&lanes(&pred), &lanes(&obs)],
            [&lanes(&pe), &lanes(&oe)],
        );
        let mut want = vec![[0f32; LANES]; q.len()];
        weigh(&mut want, &q, |x| {
            secant_weight_encoded(pred[x], obs[x], pe[x], oe[x])
        });
        assert!(
            want.as_flattened()
                .iter()
                .all(|w| w.is_finite() && *w > 0.0),
            "{want:?}"
        );
        assert_eq!(got, want);
    }
}
