//! Vector quantisation of the per-pixel vectors (seed 004, §V-C): every pixel keeps an
//! index into a codebook of `C` vectors (its stored planes' values together), found by
//! k-means.
//!
//! Neighbouring pixels' vectors are alike, so a small codebook serves a whole image;
//! and a light that is the same for every pixel (directional, environment) relights the
//! `C` entries once per frame, after which a pixel costs one table look-up
//! ([`super::relight`]).
//!
//! The search for a vector's nearest entry keeps the entries sorted along the axis of
//! greatest spread and walks outwards from the query's place on it, stopping on each
//! side once that axis alone is farther than the best distance so far; after the
//! principal-component stage most of the spread is on one axis, so few entries are
//! visited. Distances also stop summing once they pass the best.

use crate::{Error, Result};
use rayon::prelude::*;

/// Most entries a codebook may have (indices are 16-bit).
pub const MAX_ENTRIES: usize = 1 << 16;

/// Vectors k-means trains on (a regular subsample beyond): enough for every entry to
/// see many members.
const TRAINING_PER_ENTRY: usize = 64;
const MIN_TRAINING: usize = 1 << 16;
const MAX_TRAINING: usize = 1 << 19;

/// Lloyd iterations at most, and the relative fall in distortion under which they stop.
const ITERATIONS: usize = 12;
const CONVERGED: f64 = 2e-3;

/// `entries` vectors of `dims` values, sorted along `axis`.
#[derive(Clone, Debug, PartialEq)]
pub struct Codebook {
    pub dims: usize,
    /// Entry `e` is `values[e·dims .. (e+1)·dims]`.
    pub values: Vec<f32>,
}

impl Codebook {
    pub fn entries(&self) -> usize {
        self.values.len() / self.dims
    }

    pub fn entry(&self, e: usize) -> &[f32] {
        &self.values[e * self.dims..(e + 1) * self.dims]
    }
}

/// A codebook made searchable: entries sorted along `axis`, with their keys.
struct Search<'a> {
    book: &'a [f32],
    dims: usize,
    axis: usize,
    keys: Vec<f32>,
}

impl<'a> Search<'a> {
    /// `book` must already be sorted along `axis`.
    fn new(book: &'a [f32], dims: usize, axis: usize) -> Self {
        let keys = book.chunks_exact(dims).map(|e| e[axis]).collect();
        Search {
            book,
            dims,
            axis,
            keys,
        }
    }

    /// The nearest entry to `v` and its squared distance.
    fn nearest(&self, v: &[f32]) -> (usize, f32) {
        let key = v[self.axis];
        let start = self.keys.partition_point(|&k| k < key);
        let n = self.keys.len();
        let mut best = (start.min(n - 1), f32::INFINITY);
        best.1 = self.distance(v, best.0, f32::INFINITY);
        let (mut lo, mut hi) = (start, start);
        let (mut lo_open, mut hi_open) = (true, true);
        while lo_open || hi_open {
            if hi_open {
                if hi >= n {
                    hi_open = false;
                } else {
                    let gap = self.keys[hi] - key;
                    if gap * gap >= best.1 {
                        hi_open = false;
                    } else {
                        let d = self.distance(v, hi, best.1);
                        if d < best.1 {
                            best = (hi, d);
                        }
                        hi += 1;
                    }
                }
            }
            if lo_open {
                if lo == 0 {
                    lo_open = false;
                } else {
                    let gap = key - self.keys[lo - 1];
                    if gap * gap >= best.1 {
                        lo_open = false;
                    } else {
                        let d = self.distance(v, lo - 1, best.1);
                        if d < best.1 {
                            best = (lo - 1, d);
                        }
                        lo -= 1;
                    }
                }
            }
        }
        best
    }

    /// Squared distance from `v` to entry `e`, or any value ≥ `bound` once it passes it.
    #[inline]
    fn distance(&self, v: &[f32], e: usize, bound: f32) -> f32 {
        let entry = &self.book[e * self.dims..(e + 1) * self.dims];
        let mut d = 0.0f32;
        for (chunk_v, chunk_e) in v.chunks(4).zip(entry.chunks(4)) {
            for (a, b) in chunk_v.iter().zip(chunk_e) {
                d += (a - b) * (a - b);
            }
            if d >= bound {
                return d;
            }
        }
        d
    }
}

/// A tiny deterministic generator (splitmix64): the same input gives the same file.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The axis of greatest variance of `vectors`.
fn widest_axis(vectors: &[f32], dims: usize) -> usize {
    let n = (vectors.len() / dims).max(1) as f64;
    (0..dims)
        .map(|a| {
            let (s, s2) = vectors
                .chunks_exact(dims)
                .fold((0.0f64, 0.0f64), |(s, s2), v| {
                    (s + v[a] as f64, s2 + (v[a] as f64).powi(2))
                });
            (a, s2 / n - (s / n).powi(2))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0, |(a, _)| a)
}

/// Sort the entries of `book` along `axis`.
fn sort_entries(book: &mut Vec<f32>, dims: usize, axis: usize) {
    let mut entries: Vec<&[f32]> = book.chunks_exact(dims).collect();
    entries.sort_by(|a, b| a[axis].total_cmp(&b[axis]));
    *book = entries.concat();
}

/// Train a codebook of at most `entries` vectors on `vectors` (`dims` values each,
/// already scaled so that plain squared distance is the error that matters): k-means++
/// seeds on a subsample, then Lloyd iterations; entries left empty are moved to the
/// vectors worst served.
pub fn train(vectors: &[f32], dims: usize, entries: usize) -> Result<Codebook> {
    if dims == 0 || vectors.is_empty() || !vectors.len().is_multiple_of(dims) {
        return Err(Error::invalid("vector quantisation of no vectors"));
    }
    let n = vectors.len() / dims;
    let training: Vec<f32> = (0..n)
        .step_by(training_stride(n, entries))
        .flat_map(|i| vectors[i * dims..(i + 1) * dims].iter().copied())
        .collect();
    train_on(training, dims, entries)
}

/// The stride of the vectors [`train`] trains on among `n` for a codebook of `entries`:
/// every vector whose index is a multiple of it (so that a caller that cannot hold all
/// `n` vectors gathers the same ones for [`train_on`]).
pub fn training_stride(n: usize, entries: usize) -> usize {
    let wanted = entries
        .saturating_mul(TRAINING_PER_ENTRY)
        .clamp(MIN_TRAINING, MAX_TRAINING);
    (n / wanted).max(1)
}

/// [`train`] on the vectors it would take from all of them ([`training_stride`]).
pub fn train_on(training: Vec<f32>, dims: usize, entries: usize) -> Result<Codebook> {
    if dims == 0 || training.is_empty() || !training.len().is_multiple_of(dims) {
        return Err(Error::invalid("vector quantisation of no vectors"));
    }
    if !(2..=MAX_ENTRIES).contains(&entries) {
        return Err(Error::invalid(format!(
            "a codebook has 2 to {MAX_ENTRIES} entries, not {entries}"
        )));
    }
    let m = training.len() / dims;
    let entries = entries.min(m);
    let axis = widest_axis(&training, dims);
    let mut rng = Rng(0x5eed_0004);

    let mut book = seed_plus_plus(&training, dims, entries, &mut rng);
    sort_entries(&mut book, dims, axis);
    let mut previous = f64::INFINITY;
    for _ in 0..ITERATIONS {
        let search = Search::new(&book, dims, axis);
        let assigned: Vec<(usize, f32)> = training
            .par_chunks_exact(dims)
            .map(|v| search.nearest(v))
            .collect();
        let distortion: f64 = assigned.iter().map(|&(_, d)| d as f64).sum();
        let mut sums = vec![0.0f64; entries * dims];
        let mut counts = vec![0usize; entries];
        for (v, &(e, _)) in training.chunks_exact(dims).zip(&assigned) {
            counts[e] += 1;
            for (s, &x) in sums[e * dims..(e + 1) * dims].iter_mut().zip(v) {
                *s += x as f64;
            }
        }
        // Empty entries take the vectors farthest from their entries.
        let empty: Vec<usize> = (0..entries).filter(|&e| counts[e] == 0).collect();
        let mut worst: Vec<usize> = Vec::new();
        if !empty.is_empty() {
            let mut order: Vec<usize> = (0..m).collect();
            order.sort_by(|&a, &b| assigned[b].1.total_cmp(&assigned[a].1));
            worst = order.into_iter().take(empty.len()).collect();
        }
        for e in 0..entries {
            if counts[e] > 0 {
                for d in 0..dims {
                    book[e * dims + d] = (sums[e * dims + d] / counts[e] as f64) as f32;
                }
            }
        }
        for (&e, &v) in empty.iter().zip(&worst) {
            book[e * dims..(e + 1) * dims].copy_from_slice(&training[v * dims..(v + 1) * dims]);
        }
        sort_entries(&mut book, dims, axis);
        if empty.is_empty() && previous - distortion <= CONVERGED * distortion {
            break;
        }
        previous = distortion;
    }
    Ok(Codebook { dims, values: book })
}

/// k-means++ seeding (each new entry drawn with probability ∝ its squared distance to
/// the nearest entry so far) on at most 8 vectors per entry.
fn seed_plus_plus(training: &[f32], dims: usize, entries: usize, rng: &mut Rng) -> Vec<f32> {
    let m = training.len() / dims;
    // Drawn at random: a regular stride can fall in step with the image's own period.
    let pool: Vec<&[f32]> = if 8 * entries >= m {
        training.chunks_exact(dims).collect()
    } else {
        (0..8 * entries)
            .map(|_| {
                let i = rng.below(m);
                &training[i * dims..(i + 1) * dims]
            })
            .collect()
    };
    let dist =
        |a: &[f32], b: &[f32]| -> f32 { a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum() };
    let first = pool[rng.below(pool.len())];
    let mut book: Vec<f32> = first.to_vec();
    let mut nearest: Vec<f32> = pool.iter().map(|v| dist(v, first)).collect();
    while book.len() / dims < entries {
        let total: f64 = nearest.iter().map(|&d| d as f64).sum();
        let pick = if total > 0.0 {
            let mut target = rng.unit() * total;
            let mut pick = pool.len() - 1;
            for (i, &d) in nearest.iter().enumerate() {
                target -= d as f64;
                if target <= 0.0 {
                    pick = i;
                    break;
                }
            }
            pick
        } else {
            rng.below(pool.len())
        };
        let chosen = pool[pick];
        book.extend_from_slice(chosen);
        nearest
            .par_iter_mut()
            .zip(&pool)
            .for_each(|(d, v)| *d = d.min(dist(v, chosen)));
    }
    book
}

/// Finds the nearest entry of a codebook, by its index in the book.
pub struct Assigner {
    /// The entries sorted along the search's axis, and each one's index in the book.
    sorted: Vec<f32>,
    order: Vec<usize>,
    dims: usize,
    axis: usize,
}

impl Assigner {
    pub fn new(book: &Codebook) -> Assigner {
        let axis = widest_axis(&book.values, book.dims);
        // The search needs the entries sorted along its axis; keep the book's own order
        // for the indices by sorting a copy with a permutation.
        let mut order: Vec<usize> = (0..book.entries()).collect();
        order.sort_by(|&a, &b| book.entry(a)[axis].total_cmp(&book.entry(b)[axis]));
        let sorted: Vec<f32> = order
            .iter()
            .flat_map(|&e| book.entry(e).iter().copied())
            .collect();
        Assigner {
            sorted,
            order,
            dims: book.dims,
            axis,
        }
    }

    /// The nearest entry for every vector (`dims` values each, one after another).
    pub fn assign(&self, vectors: &[f32]) -> Vec<u16> {
        let search = Search::new(&self.sorted, self.dims, self.axis);
        vectors
            .par_chunks_exact(self.dims)
            .map(|v| self.order[search.nearest(v).0] as u16)
            .collect()
    }
}

/// The nearest entry of `book` for every vector.
pub fn assign(book: &Codebook, vectors: &[f32]) -> Vec<u16> {
    Assigner::new(book).assign(vectors)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(book: &Codebook, v: &[f32]) -> f32 {
        (0..book.entries())
            .map(|e| {
                book.entry(e)
                    .iter()
                    .zip(v)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f32>()
            })
            .fold(f32::INFINITY, f32::min)
    }

    fn clusters(n: usize, dims: usize) -> Vec<f32> {
        let mut rng = Rng(7);
        (0..n)
            .flat_map(|i| {
                let c = (i % 5) as f32;
                (0..dims)
                    .map(|d| c * (d as f32 + 1.0) + 0.05 * (rng.unit() as f32 - 0.5))
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    #[test]
    fn the_pruned_search_finds_the_true_nearest_entry() {
        let dims = 7;
        let mut rng = Rng(3);
        let vectors: Vec<f32> = (0..20_000 * dims)
            .map(|i| (rng.unit() as f32 - 0.5) * if i % dims == 0 { 10.0 } else { 1.0 })
            .collect();
        let book = train(&vectors, dims, 64).unwrap();
        let idx = assign(&book, &vectors[..2000 * dims]);
        for (v, &e) in vectors.chunks_exact(dims).zip(&idx) {
            let d: f32 = book
                .entry(e as usize)
                .iter()
                .zip(v)
                .map(|(a, b)| (a - b) * (a - b))
                .sum();
            assert!((d - brute(&book, v)).abs() <= 1e-5 * d.max(1.0), "{d}");
        }
    }

    #[test]
    fn k_means_finds_well_separated_clusters() {
        let dims = 5;
        let vectors = clusters(5000, dims);
        let book = train(&vectors, dims, 5).unwrap();
        let idx = assign(&book, &vectors);
        for (v, &e) in vectors.chunks_exact(dims).zip(&idx) {
            for (a, b) in book.entry(e as usize).iter().zip(v) {
                assert!((a - b).abs() < 0.05, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn bad_sizes_are_refused() {
        assert!(train(&[1.0, 2.0], 2, 1).is_err());
        assert!(train(&[1.0, 2.0], 2, MAX_ENTRIES + 1).is_err());
        assert!(train(&[], 2, 4).is_err());
        assert!(train(&[1.0, 2.0, 3.0], 2, 4).is_err());
    }
}
