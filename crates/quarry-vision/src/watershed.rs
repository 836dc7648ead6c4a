//! Priority-flood (Meyer) watershed, spec 004 §2.5.
//!
//! Every regional minimum seeds one region; pixels are flooded in order of the key
//! `(max(level of the flooding pixel, own value), arrival sequence)`: a pixel lower than the
//! current flood level is flooded *at* that level, and equal levels are served first-in
//! first-out. Labels are assigned when a pixel is pushed, each pixel is pushed once, seeds are
//! pushed in raster order and neighbours visited in the fixed N8 (or N4) order, so the result is
//! fully deterministic. There are no watershed lines: every pixel gets a label in 1..K
//! ([`boundary_mask`] gives a display-only boundary).
//!
//! # Implementation: labellers instead of a priority queue
//!
//! In the priority-queue flood every pixel `q` other than a seed takes the label of its
//! *labeller*, the neighbour whose pop pushed it. Two exact shortcuts replace the queue:
//!
//! **Descent flood** (used whenever it applies). When every regional minimum holds a seed,
//! no pixel is ever reached from above its own value (a lower unlabelled pixel would have a
//! non-increasing path to a seed, all of whose pixels were popped earlier), so every pixel's key
//! is its own value `B(q)` and pixels pop in `(B, push order)` order. The labeller of `q` is
//! then simply its first-popped neighbour:
//!
//! - the unique lowest neighbour, when one neighbour is strictly lowest and lower than `q`
//!   (after the ramp and a float blur, all but a handful of pixels);
//! - among several equally low neighbours, the first pushed. Push order is a pixel's rank
//!   among equal values: seeds first in raster order, any other pixel by the rank of its own
//!   labeller and then the visiting order of that pop, compared by walking both labeller chains
//!   (`Descent::rank_cmp`);
//! - inside a plateau without a lower neighbour, the level's first-in-first-out flood,
//!   replayed per plateau component from its entry pixels sorted by rank.
//!
//! One row-wise pass (vectorised; AVX2 and AVX-512F builds are dispatched at run time by
//! `crate::simd`) codes each pixel with the direction of its lowest neighbour or a tie/plateau/pit
//! marker; the few tie and plateau pixels are resolved in value order; one sweep then copies labels
//! down the labeller chains. [`RampBlurWatershed`](crate::RampBlurWatershed) and [`watershed`] also
//! take the seeds from that pass: when no pixel is a plateau pixel, the regional minima are exactly
//! the pixels below all their neighbours, so the minima need no pass of their own.
//!
//! **Presorted flood** (the fallback: seeds that leave a regional minimum unseeded, a `-0.0`
//! value, where `==` and `total_cmp` disagree, or a pathological relief that exhausts the
//! rank-comparison budget). A pushed pixel higher than the flood level has the static key
//! `B(q)`, a lower one joins the FIFO of the current level, so the heap order is reproduced by
//! sorting all pixels once by `B` (a counting sort into value buckets followed by tiny
//! per-bucket sorts) and walking that order: at the group of pixels with value `v` the pixels
//! already labelled are exactly the static items of key `v`; they are popped in push order,
//! then the FIFO of items pushed at level `v` is drained.
//!
//! Both give results identical to the priority-queue formulation, tested against a binary-heap
//! reference on random reliefs with many ties and plateaus (minima seeds, extra seeds, random
//! seeds; f64 and f32), and on `photo_gray` (labels pinned by digests).

use crate::VisionError;
use crate::minima::{Connectivity, Minima, Relief, check_relief, regional_minima};
use crate::simd::{isa, multiversion};
use quarry_core::{MinimumInfo, Plane, Segmentation};

/// Options of [`flood`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct WatershedOptions {
    /// Neighbourhood used to grow regions (8 by default, as in spec 004).
    pub connectivity: Connectivity,
}

/// An order-preserving u64 image of a finite f64 (`total_cmp` order).
#[inline]
fn level_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 { !b } else { b | (1 << 63) }
}

/// Inverse of [`level_key`].
#[cfg(test)]
#[inline]
fn key_level(k: u64) -> f64 {
    if k >> 63 == 1 {
        f64::from_bits(k & !(1 << 63))
    } else {
        f64::from_bits(!k)
    }
}

/// The input checks of a flood: a valid relief, seeds of the same size, at least one seed, seed
/// labels in `0..=K`. Returns `K`.
pub(crate) fn check_flood_input<T: Relief>(
    relief: &Plane<T>,
    seeds: &Minima,
) -> Result<u32, VisionError> {
    check_relief(relief, "watershed")?;
    if relief.dimensions() != seeds.labels.dimensions() {
        return Err(VisionError::SizeMismatch {
            what: "watershed relief vs seeds",
            a: relief.dimensions(),
            b: seeds.labels.dimensions(),
        });
    }
    let k = seeds.minima.len() as u32;
    if k == 0 {
        return Err(quarry_core::CoreError::Empty {
            what: "watershed seeds",
        }
        .into());
    }
    if let Some(&bad) = seeds.labels.data.iter().find(|&&l| l > k) {
        return Err(quarry_core::CoreError::invalid(
            "seed label",
            format!("{bad} is not in 0..={k}"),
        )
        .into());
    }
    Ok(k)
}

/// Floods `relief` from `seeds` (Algorithm WS of spec 004 §2.5). `seeds.labels` gives the seed
/// label of each seed pixel (0 elsewhere) and `seeds.minima` the seed records, copied into the
/// result.
///
/// Errors: empty relief, NaN/infinite values, size mismatch between relief and seeds, seed
/// labels outside 1..=K, no seed at all.
pub fn flood<T: Relief>(
    relief: &Plane<T>,
    seeds: &Minima,
    options: WatershedOptions,
) -> Result<Segmentation, VisionError> {
    check_flood_input(relief, seeds)?;
    let mut labels = seeds.labels.data.clone();
    flood_labels(
        &relief.data,
        relief.width as usize,
        &mut labels,
        options.connectivity,
    );
    Ok(Segmentation {
        labels: Plane {
            width: relief.width,
            height: relief.height,
            data: labels,
        },
        minima: seeds.minima.clone(),
    })
}

/// [`flood`] from seeds computed by [`regional_minima`] on the same relief (hence valid), reusing
/// their label buffer instead of copying it.
pub(crate) fn flood_minima<T: Relief>(
    relief: &Plane<T>,
    seeds: Minima,
    options: WatershedOptions,
) -> Segmentation {
    let Minima { mut labels, minima } = seeds;
    flood_labels(
        &relief.data,
        relief.width as usize,
        &mut labels.data,
        options.connectivity,
    );
    Segmentation { labels, minima }
}

/// `(level_key, pixel)` of every pixel, sorted (ties of equal keys by pixel index).
///
/// A stable counting sort into about n/2 value buckets (the bucket index
/// `⌊(v − v_min)·scale⌋` is monotone in `v` under IEEE rounding) and a small sort per bucket.
#[inline(never)]
fn sorted_pixels<T: Relief>(d: &[T]) -> Vec<(u64, u32)> {
    let n = d.len();
    let (vmin, vmax) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            let v = v.to_f64();
            (lo.min(v), hi.max(v))
        });
    let nb = (n / 2).clamp(1, 1 << 22);
    let range = vmax - vmin;
    let scale = if range.is_finite() && range > 0.0 {
        (nb - 1) as f64 / range
    } else {
        0.0
    };
    let scale = if scale.is_finite() { scale } else { 0.0 };
    // NaN/negative casts saturate to 0; `min` guards the top
    let bucket = |v: f64| (((v - vmin) * scale) as usize).min(nb - 1);
    let mut start = vec![0u32; nb + 1];
    for v in d {
        start[bucket(v.to_f64()) + 1] += 1;
    }
    for b in 0..nb {
        start[b + 1] += start[b];
    }
    let mut fill = start.clone();
    let mut out = vec![(0u64, 0u32); n];
    for (p, v) in d.iter().enumerate() {
        let v = v.to_f64();
        let b = bucket(v);
        out[fill[b] as usize] = (level_key(v), p as u32);
        fill[b] += 1;
    }
    for b in 0..nb {
        let s = &mut out[start[b] as usize..start[b + 1] as usize];
        match s.len() {
            0 | 1 => {}
            2..=32 => insertion_sort(s),
            _ => s.sort_unstable(),
        }
    }
    out
}

fn insertion_sort(s: &mut [(u64, u32)]) {
    for i in 1..s.len() {
        let x = s[i];
        let mut j = i;
        while j > 0 && s[j - 1] > x {
            s[j] = s[j - 1];
            j -= 1;
        }
        s[j] = x;
    }
}

/// The flood proper on raw data: `labels` holds the seeds on entry and every pixel's label on
/// exit (see the module documentation for why this equals the priority-queue order).
fn flood_sorted<T: Relief>(d: &[T], w: usize, labels: &mut [u32], connectivity: Connectivity) {
    let n = d.len();
    let h = n / w;
    let sorted = sorted_pixels(d);
    // pixels sharing their value with another pixel (members of a tie group): only their push
    // order matters, so only they get a sequence number
    let mut tie = Bits::new(n);
    for pair in sorted.windows(2) {
        if pair[0].0 == pair[1].0 {
            tie.set(pair[0].1 as usize);
            tie.set(pair[1].1 as usize);
        }
    }
    let mut edge = Bits::new(n);
    for x in 0..w {
        edge.set(x);
        edge.set((h - 1) * w + x);
    }
    for y in 0..h {
        edge.set(y * w);
        edge.set(y * w + w - 1);
    }
    // push order of the static items (seeds in raster order first), stored for tie pixels only
    // (`vec!` of zeros is lazily mapped: untouched pages cost nothing)
    let mut seq = vec![0u32; n];
    let mut next_seq = 0u32;
    for (p, &l) in labels.iter().enumerate() {
        if l != 0 {
            if tie.get(p) {
                seq[p] = next_seq;
            }
            next_seq += 1;
        }
    }
    let offs = connectivity.offsets();
    let lin: Vec<isize> = offs
        .iter()
        .map(|&(dx, dy)| dy as isize * w as isize + dx as isize)
        .collect();
    let mut st = FloodState {
        d,
        w,
        h,
        labels,
        seq: &mut seq,
        next_seq,
        fifo: Vec::new(),
        offs,
        lin: &lin,
        tie: &tie,
        edge: &edge,
    };
    let mut group: Vec<(u32, u32)> = Vec::new();
    let mut i = 0;
    while i < n {
        let (lkey, p0) = sorted[i];
        let mut j = i + 1;
        while j < n && sorted[j].0 == lkey {
            j += 1;
        }
        if j == i + 1 {
            if st.labels[p0 as usize] != 0 {
                st.expand(p0 as usize, lkey);
            }
        } else {
            group.clear();
            group.extend(
                sorted[i..j]
                    .iter()
                    .filter(|&&(_, p)| st.labels[p as usize] != 0)
                    .map(|&(_, p)| (st.seq[p as usize], p)),
            );
            group.sort_unstable();
            for &(_, p) in &group {
                st.expand(p as usize, lkey);
            }
        }
        let mut head = 0;
        while head < st.fifo.len() {
            let p = st.fifo[head];
            head += 1;
            st.expand(p as usize, lkey);
        }
        st.fifo.clear();
        i = j;
    }
}

/// Pixel code of a seed (codes `0..K` name a pixel's labeller by its position in the
/// connectivity's visiting order).
const SEED: u8 = 250;
/// Code of a pixel whose lowest neighbours tie (resolved by [`Descent::rank_cmp`]).
const TIE: u8 = 251;
/// Code of a non-seed pixel without a strictly lower neighbour (inside a plateau).
const PLATEAU: u8 = 252;
/// Code of a non-seed pixel below all its neighbours (a strict local minimum).
const PIT: u8 = 253;

/// The descent flood could not prove its shortcut (an unseeded regional minimum, a `-0.0`
/// value, or the comparison budget ran out on a pathological relief); the sorted flood runs
/// instead.
struct Bail;

/// The flood proper: the descent flood when it applies, the presorted flood otherwise (both give
/// the priority-queue order exactly).
fn flood_labels<T: Relief>(d: &[T], w: usize, labels: &mut [u32], connectivity: Connectivity) {
    if flood_descent(d, w, labels, connectivity).is_err() {
        flood_sorted(d, w, labels, connectivity);
    }
}

/// Per-row buffers of [`code_row`].
struct RowScratch<T> {
    min: Vec<T>,
    mask: Vec<u8>,
}

/// `code of a pixel` from the bit mask of its neighbours equal to the least one: the single
/// set bit's position, or [`TIE`] for several.
const MASK_CODE: [u8; 256] = {
    let mut t = [TIE; 256];
    let mut k = 0;
    while k < 8 {
        t[1 << k] = k as u8;
        k += 1;
    }
    t
};

multiversion!(avx512, avx2:
    /// The codes of one row of interior pixels `c` (not seeds) from their neighbour rows `nb` in
    /// visiting order; also compiled for AVX2 and AVX-512F and dispatched at run time
    /// ([`crate::simd`]; the comparisons are exact, so every build gives the same codes, tested).
    #[inline]
    fn code_row<[T: Relief, const K: usize]> => code_row_body(
        c: &[T],
        nb: [&[T]; K],
        out: &mut [u8],
        scratch: &mut RowScratch<T>,
    )
);

/// [`code_row`] as whole-row passes the compiler vectorises: the least neighbour, the mask of
/// the neighbours equal to it, then the code.
#[allow(clippy::inline_always)]
#[inline(always)]
fn code_row_body<T: Relief, const K: usize>(
    c: &[T],
    nb: [&[T]; K],
    out: &mut [u8],
    scratch: &mut RowScratch<T>,
) {
    let l = c.len();
    let m = &mut scratch.min[..l];
    let mask = &mut scratch.mask[..l];
    m.copy_from_slice(&nb[0][..l]);
    for row in &nb[1..] {
        for (m, &v) in m.iter_mut().zip(&row[..l]) {
            *m = if v < *m { v } else { *m };
        }
    }
    mask.fill(0);
    for (k, row) in nb.iter().enumerate() {
        for (b, (&v, &m)) in mask.iter_mut().zip(row[..l].iter().zip(m.iter())) {
            *b |= u8::from(v == m) << k;
        }
    }
    for ((o, &b), (&m, &v)) in out.iter_mut().zip(mask.iter()).zip(m.iter().zip(c)) {
        *o = if m < v {
            MASK_CODE[usize::from(b)]
        } else if m == v {
            PLATEAU
        } else {
            PIT
        };
    }
}

/// Codes every pixel (see [`SEED`]): seeds where `labels` is non-zero, the direction of the
/// unique lowest neighbour when it is lower than the pixel, or [`TIE`] / [`PLATEAU`] / [`PIT`].
/// Comparisons are the type's own (`<`, `==`), equal to `total_cmp` on finite values without
/// `-0.0` (the caller rules those out).
fn classify<T: Relief>(
    d: &[T],
    w: usize,
    labels: Option<&[u32]>,
    connectivity: Connectivity,
    codes: &mut [u8],
) {
    let n = d.len();
    let h = n / w;
    let offs = connectivity.offsets();
    let eight = connectivity == Connectivity::Eight;
    let mut scratch = RowScratch {
        min: d[..w].to_vec(),
        mask: vec![0; w],
    };
    let level = isa();
    for y in 0..h {
        let row = y * w;
        let out = &mut codes[row..row + w];
        if y > 0 && y + 1 < h && w > 2 {
            let (up, mid, down) = (&d[row - w..row], &d[row..row + w], &d[row + w..row + 2 * w]);
            let l = w - 2;
            let c = &mid[1..=l];
            let inner = &mut out[1..=l];
            if eight {
                let nb = [
                    &up[..l],
                    &up[1..=l],
                    &up[2..],
                    &mid[..l],
                    &mid[2..],
                    &down[..l],
                    &down[1..=l],
                    &down[2..],
                ];
                code_row(level, c, nb, inner, &mut scratch);
            } else {
                code_row(
                    level,
                    c,
                    [&up[1..=l], &mid[..l], &mid[2..], &down[1..=l]],
                    inner,
                    &mut scratch,
                );
            }
        }
        // the image border, with bounds checks
        let edge = |x: usize| -> u8 {
            let c = d[row + x];
            let mut vals = [c; 8];
            let mut m = None;
            for (k, &(dx, dy)) in offs.iter().enumerate() {
                let (qx, qy) = (x as isize + dx as isize, y as isize + dy as isize);
                if qx >= 0 && qy >= 0 && qx < w as isize && qy < h as isize {
                    let v = d[qy as usize * w + qx as usize];
                    vals[k] = v;
                    if m.is_none_or(|m| v < m) {
                        m = Some(v);
                    }
                }
            }
            let Some(m) = m else { return PIT };
            let mut first = None;
            let mut cnt = 0;
            for (k, &(dx, dy)) in offs.iter().enumerate() {
                let (qx, qy) = (x as isize + dx as isize, y as isize + dy as isize);
                if qx >= 0 && qy >= 0 && qx < w as isize && qy < h as isize && vals[k] == m {
                    cnt += 1;
                    first = first.or(Some(k as u8));
                }
            }
            if m < c {
                if cnt == 1 { first.unwrap_or(TIE) } else { TIE }
            } else if m == c {
                PLATEAU
            } else {
                PIT
            }
        };
        if y == 0 || y + 1 == h || w <= 2 {
            for (x, o) in out.iter_mut().enumerate() {
                *o = edge(x);
            }
        } else {
            out[0] = edge(0);
            out[w - 1] = edge(w - 1);
        }
        if let Some(l) = labels {
            for (o, &l) in out.iter_mut().zip(&l[row..row + w]) {
                if l != 0 {
                    *o = SEED;
                }
            }
        }
    }
}

/// True when some value is `-0.0` (where `==` and `total_cmp` disagree).
fn has_negative_zero<T: Relief>(d: &[T]) -> bool {
    d.iter().fold(false, |a, v| {
        a | (v.to_f64().to_bits() == (-0.0f64).to_bits())
    })
}

/// The descent flood (see the module documentation): every pixel takes the label of its
/// *labeller*, the neighbour whose pop pushed it in the priority-queue flood. When every
/// regional minimum holds a seed, all keys equal the pixels' own values and the labeller is
/// the neighbour of least `(value, push order)`; only ties need the push order, which is
/// compared through the labellers' own ranks (`Descent::rank_cmp`).
///
/// Leaves `labels` as it found it when it returns `Err`.
fn flood_descent<T: Relief>(
    d: &[T],
    w: usize,
    labels: &mut [u32],
    connectivity: Connectivity,
) -> Result<(), Bail> {
    if has_negative_zero(d) {
        return Err(Bail);
    }
    let mut codes = vec![0u8; d.len()];
    classify(d, w, Some(labels), connectivity, &mut codes);
    resolve(d, w, labels, connectivity, &mut codes)
}

/// Segments a relief from its own regional minima when none of them is a plateau (each is then
/// a pixel below all its neighbours, found by the same pass that codes the labellers); `None`
/// when a plateau or a `-0.0` value needs the general path (`regional_minima` + [`flood`]).
pub(crate) fn segment_descent<T: Relief>(
    relief: &Plane<T>,
    connectivity: Connectivity,
) -> Option<Segmentation> {
    let d = &relief.data;
    let w = relief.width as usize;
    if d.is_empty() || has_negative_zero(d) {
        return None;
    }
    let mut codes = vec![0u8; d.len()];
    classify(d, w, None, connectivity, &mut codes);
    if codes.contains(&PLATEAU) {
        return None;
    }
    let mut labels = vec![0u32; d.len()];
    let mut minima = Vec::new();
    for (p, c) in codes.iter_mut().enumerate() {
        if *c == PIT {
            *c = SEED;
            let id = minima.len() as u32 + 1;
            labels[p] = id;
            minima.push(MinimumInfo {
                id,
                representative: ((p % w) as u32, (p / w) as u32),
                size: 1,
                value: d[p].to_f64(),
            });
        }
    }
    resolve(d, w, &mut labels, connectivity, &mut codes).ok()?;
    Some(Segmentation {
        labels: Plane {
            width: relief.width,
            height: relief.height,
            data: labels,
        },
        minima,
    })
}

/// Resolves the tie and plateau codes, then labels every pixel from its labeller.
fn resolve<T: Relief>(
    d: &[T],
    w: usize,
    labels: &mut [u32],
    connectivity: Connectivity,
    codes: &mut [u8],
) -> Result<(), Bail> {
    let n = d.len();
    let offs = connectivity.offsets();
    let lin: Vec<isize> = offs
        .iter()
        .map(|&(dx, dy)| dy as isize * w as isize + dx as isize)
        .collect();
    if codes.contains(&PIT) {
        // a non-seed pixel below all its neighbours: an unseeded regional minimum
        return Err(Bail);
    }
    let mut hard: Vec<(u64, u32)> = codes
        .iter()
        .enumerate()
        .filter(|&(_, &c)| c == TIE || c == PLATEAU)
        .map(|(p, _)| (level_key(d[p].to_f64()), p as u32))
        .collect();
    if !hard.is_empty() {
        hard.sort_unstable();
        let mut ctx = Descent {
            d,
            w,
            h: n / w,
            offs,
            lin: &lin,
            codes: &mut *codes,
            budget: 64 * n + 4096,
            seen: Bits::new(0),
            stack: Vec::new(),
            entries: Vec::new(),
            queue: Vec::new(),
        };
        let mut i = 0;
        while i < hard.len() {
            let k = hard[i].0;
            let mut j = i + 1;
            while j < hard.len() && hard[j].0 == k {
                j += 1;
            }
            // ties first: plateau entries at this level may be tie pixels themselves
            for &(_, p) in &hard[i..j] {
                let p = p as usize;
                if ctx.codes[p] == TIE {
                    ctx.codes[p] = ctx.tie_code(p)?;
                }
            }
            for &(_, p) in &hard[i..j] {
                let p = p as usize;
                if ctx.codes[p] == PLATEAU {
                    ctx.plateau(p, k)?;
                }
            }
            i = j;
        }
    }
    // every non-seed pixel now names its labeller (of lower rank, so the chains end at seeds);
    // a pixel's label is its chain's seed whatever the order in which labels are copied. A
    // backward pass first labels the pixels whose labeller comes later in raster order and is
    // labelled by then (whole chains of such steps, e.g. slopes falling down the image), so that
    // the forward pass below finds most labellers labelled and rarely chases a chain far ahead
    // in the image (a cache miss per step)
    for p in (0..n).rev() {
        if labels[p] != 0 {
            continue;
        }
        if let Some(&o) = lin.get(usize::from(codes[p]))
            && o > 0
            && let Some(&l) = labels.get(p.wrapping_add_signed(o))
        {
            labels[p] = l;
        }
    }
    let mut stack: Vec<usize> = Vec::new();
    for p in 0..n {
        if labels[p] != 0 {
            continue;
        }
        // most labellers are labelled already (above or to the left, or chased before)
        if let Some(&o) = lin.get(usize::from(codes[p])) {
            let l = labels[p.wrapping_add_signed(o)];
            if l != 0 {
                labels[p] = l;
                continue;
            }
        }
        let mut q = p;
        while labels[q] == 0 {
            stack.push(q);
            let Some(&o) = lin.get(usize::from(codes[q])) else {
                // unreachable by construction; undo and let the sorted flood run
                for (l, &c) in labels.iter_mut().zip(codes.iter()) {
                    if c != SEED {
                        *l = 0;
                    }
                }
                return Err(Bail);
            };
            q = q.wrapping_add_signed(o);
        }
        let l = labels[q];
        for s in stack.drain(..) {
            labels[s] = l;
        }
    }
    Ok(())
}

/// The state of the tie and plateau resolution of [`resolve`].
struct Descent<'a, T> {
    d: &'a [T],
    w: usize,
    h: usize,
    offs: &'static [(i32, i32)],
    lin: &'a [isize],
    /// pixel codes (labeller directions once resolved)
    codes: &'a mut [u8],
    /// rank-comparison steps left before giving up
    budget: usize,
    /// pixels already gathered into a plateau component (allocated on first use)
    seen: Bits,
    stack: Vec<usize>,
    entries: Vec<usize>,
    queue: Vec<usize>,
}

impl<T: Relief> Descent<'_, T> {
    #[inline]
    fn key(&self, p: usize) -> u64 {
        level_key(self.d[p].to_f64())
    }

    /// `(visiting-order position, pixel)` of the in-image neighbours of `p`.
    fn neighbours(&self, p: usize) -> impl Iterator<Item = (u8, usize)> + use<T> {
        let (w, h) = (self.w as isize, self.h as isize);
        let (x, y) = ((p % self.w) as isize, (p / self.w) as isize);
        self.offs
            .iter()
            .enumerate()
            .filter_map(move |(k, &(dx, dy))| {
                let (qx, qy) = (x + dx as isize, y + dy as isize);
                (qx >= 0 && qy >= 0 && qx < w && qy < h).then(|| (k as u8, (qy * w + qx) as usize))
            })
    }

    /// Order of `x` and `y` in the priority-queue pop sequence: by key, then by push order.
    /// Seeds are pushed first, in raster order; any other pixel is pushed during its
    /// labeller's pop, in that pop's visiting order.
    fn rank_cmp(&mut self, mut x: usize, mut y: usize) -> Result<std::cmp::Ordering, Bail> {
        use std::cmp::Ordering;
        loop {
            if x == y {
                return Ok(Ordering::Equal);
            }
            let (kx, ky) = (self.key(x), self.key(y));
            if kx != ky {
                return Ok(kx.cmp(&ky));
            }
            let (cx, cy) = (self.codes[x], self.codes[y]);
            match (cx == SEED, cy == SEED) {
                (true, true) => return Ok(x.cmp(&y)),
                (true, false) => return Ok(Ordering::Less),
                (false, true) => return Ok(Ordering::Greater),
                (false, false) => {}
            }
            let (Some(&ox), Some(&oy)) =
                (self.lin.get(usize::from(cx)), self.lin.get(usize::from(cy)))
            else {
                // an unresolved labeller cannot occur in processing order; give up safely
                return Err(Bail);
            };
            if self.budget == 0 {
                return Err(Bail);
            }
            self.budget -= 1;
            let (px, py) = (x.wrapping_add_signed(ox), y.wrapping_add_signed(oy));
            if px == py {
                // pushed by the same pop: in its visiting order, i.e. by the opposite direction
                return Ok(cy.cmp(&cx));
            }
            (x, y) = (px, py);
        }
    }

    /// The labeller code of a tie pixel: the first popped of its lowest neighbours.
    fn tie_code(&mut self, p: usize) -> Result<u8, Bail> {
        let best = self
            .neighbours(p)
            .map(|(_, q)| self.key(q))
            .min()
            .unwrap_or(u64::MAX);
        let lowest: Vec<(u8, usize)> = self
            .neighbours(p)
            .filter(|&(_, q)| self.key(q) == best)
            .collect();
        let mut cur = lowest.first().copied().ok_or(Bail)?;
        for &q in &lowest[1..] {
            if self.rank_cmp(q.1, cur.1)?.is_lt() {
                cur = q;
            }
        }
        Ok(cur.0)
    }

    /// Floods the plateau component of interior pixel `s` (key `k`) exactly as the level-`k`
    /// FIFO does: its entries (seeds, or pixels with a lower neighbour, adjacent to the
    /// component) are popped in push order, then the first-in-first-out queue.
    fn plateau(&mut self, s: usize, k: u64) -> Result<(), Bail> {
        if self.seen.0.is_empty() {
            self.seen = Bits::new(self.d.len());
        }
        self.entries.clear();
        self.stack.clear();
        self.stack.push(s);
        self.seen.set(s);
        while let Some(c) = self.stack.pop() {
            for (_, q) in self.neighbours(c) {
                if self.key(q) != k {
                    continue;
                }
                if self.codes[q] == PLATEAU {
                    if !self.seen.get(q) {
                        self.seen.set(q);
                        self.stack.push(q);
                    }
                } else {
                    self.entries.push(q);
                }
            }
        }
        if self.entries.is_empty() {
            // an unseeded regional minimum
            return Err(Bail);
        }
        self.entries.sort_unstable();
        self.entries.dedup();
        let mut entries = std::mem::take(&mut self.entries);
        let sorted = self.merge_sort_by_rank(&mut entries);
        self.entries = entries;
        sorted?;
        self.queue.clear();
        self.queue.extend_from_slice(&self.entries);
        let last = self.offs.len() - 1;
        let mut head = 0;
        while head < self.queue.len() {
            let e = self.queue[head];
            head += 1;
            for (dir, q) in self.neighbours(e) {
                // `seen`: members of this component only (an entry may also touch another
                // interior component of the same level, flooded with its own entries)
                if self.codes[q] == PLATEAU && self.seen.get(q) {
                    // q's labeller e lies in the opposite direction
                    self.codes[q] = (last - usize::from(dir)) as u8;
                    self.queue.push(q);
                }
            }
        }
        Ok(())
    }

    /// Stable bottom-up merge sort of `v` by [`Self::rank_cmp`] (fallible, so not `sort_by`).
    fn merge_sort_by_rank(&mut self, v: &mut Vec<usize>) -> Result<(), Bail> {
        let n = v.len();
        let mut buf = vec![0usize; n];
        let mut width = 1;
        while width < n {
            let mut lo = 0;
            while lo < n {
                let mid = (lo + width).min(n);
                let hi = (lo + 2 * width).min(n);
                let (mut i, mut j, mut o) = (lo, mid, lo);
                while i < mid && j < hi {
                    if self.rank_cmp(v[j], v[i])?.is_lt() {
                        buf[o] = v[j];
                        j += 1;
                    } else {
                        buf[o] = v[i];
                        i += 1;
                    }
                    o += 1;
                }
                buf[o..o + (mid - i)].copy_from_slice(&v[i..mid]);
                o += mid - i;
                buf[o..o + (hi - j)].copy_from_slice(&v[j..hi]);
                lo = hi;
            }
            std::mem::swap(v, &mut buf);
            width *= 2;
        }
        Ok(())
    }
}

struct FloodState<'a, T> {
    d: &'a [T],
    w: usize,
    h: usize,
    labels: &'a mut [u32],
    seq: &'a mut [u32],
    next_seq: u32,
    fifo: Vec<u32>,
    offs: &'static [(i32, i32)],
    lin: &'a [isize],
    tie: &'a Bits,
    edge: &'a Bits,
}

/// A fixed-size bit set over pixel indices.
struct Bits(Vec<u64>);

impl Bits {
    fn new(n: usize) -> Self {
        Self(vec![0; n.div_ceil(64)])
    }
    #[inline]
    fn set(&mut self, i: usize) {
        self.0[i >> 6] |= 1 << (i & 63);
    }
    #[inline]
    fn get(&self, i: usize) -> bool {
        self.0[i >> 6] >> (i & 63) & 1 == 1
    }
}

impl<T: Relief> FloodState<'_, T> {
    /// Pops `p` at level `lkey`: labels its unlabelled neighbours (static push when higher than
    /// the level, FIFO push otherwise).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn expand(&mut self, p: usize, lkey: u64) {
        let lab = self.labels[p];
        if self.edge.get(p) {
            let (w, h) = (self.w, self.h);
            let (x, y) = (p % w, p / w);
            for &(dx, dy) in self.offs {
                let (qx, qy) = (x as isize + dx as isize, y as isize + dy as isize);
                if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                    continue;
                }
                self.visit(qy as usize * w + qx as usize, lab, lkey);
            }
        } else {
            for &o in self.lin {
                let q = p.wrapping_add_signed(o);
                self.visit(q, lab, lkey);
            }
        }
    }

    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn visit(&mut self, q: usize, lab: u32, lkey: u64) {
        if self.labels[q] == 0 {
            self.labels[q] = lab;
            if level_key(self.d[q].to_f64()) > lkey {
                if self.tie.get(q) {
                    self.seq[q] = self.next_seq;
                }
                self.next_seq += 1;
            } else {
                self.fifo.push(q as u32);
            }
        }
    }
}

/// Regional minima of `relief` followed by [`flood`] from them. When no minimum is a plateau the
/// minima come from the flood's own first pass (the result is the same).
///
/// Errors: empty relief, NaN/infinite values, more than 2³² − 2 pixels.
pub fn watershed<T: Relief>(
    relief: &Plane<T>,
    options: WatershedOptions,
) -> Result<Segmentation, VisionError> {
    check_relief(relief, "watershed")?;
    if let Some(s) = segment_descent(relief, options.connectivity) {
        return Ok(s);
    }
    let seeds = regional_minima(relief, options.connectivity)?;
    flood(relief, &seeds, options)
}

/// Display-only boundary: pixels with a 4-neighbour of another label.
pub fn boundary_mask(labels: &Plane<u32>) -> Plane<bool> {
    let (w, h) = (labels.width as usize, labels.height as usize);
    let d = &labels.data;
    Plane::from_fn(labels.width, labels.height, |x, y| {
        let (x, y) = (x as usize, y as usize);
        let l = d[y * w + x];
        (x + 1 < w && d[y * w + x + 1] != l)
            || (y + 1 < h && d[(y + 1) * w + x] != l)
            || (x > 0 && d[y * w + x - 1] != l)
            || (y > 0 && d[(y - 1) * w + x] != l)
    })
}

/// The previous implementation (hierarchical bucket queue in front of a binary heap on
/// `(level, seq)`), kept as the reference the presorted flood must reproduce exactly.
#[cfg(test)]
pub(crate) mod reference {
    use super::WatershedOptions;
    use super::{key_level, level_key};
    use crate::VisionError;
    use crate::minima::{Minima, Relief};
    use quarry_core::{Plane, Segmentation};
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;

    type Item = Reverse<(u64, u64, u32)>;

    /// A monotone priority queue over `(level, seq)` for the flood: a hierarchical queue of about
    /// n/64 coarse buckets (the level range split evenly) in front of an exact binary heap that
    /// holds only the current bucket. Flood levels never decrease, so the current bucket index only
    /// grows; items of later buckets wait in plain vectors. Pop order equals that of one binary heap
    /// on `(level.total_cmp, seq)` (tested), at O(1) per push and O(log m) per pop with m items per
    /// bucket.
    pub(crate) struct BucketQueue {
        vmin: f64,
        scale: f64,
        buckets: Vec<Vec<Item>>,
        cur: usize,
        heap: BinaryHeap<Item>,
        seq: u64,
    }

    impl BucketQueue {
        pub(crate) fn new(vmin: f64, vmax: f64, n: usize) -> Self {
            // few enough bucket headers to stay cache-resident, ~64 items per bucket on average
            let nb = (n / 64).clamp(1, 1 << 16);
            let range = vmax - vmin;
            let scale = if range.is_finite() && range > 0.0 {
                (nb - 1) as f64 / range
            } else {
                0.0
            };
            Self {
                vmin,
                scale: if scale.is_finite() { scale } else { 0.0 },
                buckets: (0..nb).map(|_| Vec::new()).collect(),
                cur: 0,
                heap: BinaryHeap::new(),
                seq: 0,
            }
        }

        /// Pushes `v` at `level` (`key = level_key(level)`); `level` must not be below the last
        /// popped level.
        #[inline]
        pub(crate) fn push(&mut self, level: f64, key: u64, v: u32) {
            let seq = self.seq;
            self.seq += 1;
            // monotone in `level` (IEEE subtraction and scaling are monotone); NaN casts to 0
            let idx = (((level - self.vmin) * self.scale) as usize).min(self.buckets.len() - 1);
            if idx <= self.cur {
                self.heap.push(Reverse((key, seq, v)));
            } else {
                self.buckets[idx].push(Reverse((key, seq, v)));
            }
        }

        /// Pops the least `(level, seq)`: returns `(level key, value)`.
        #[inline]
        pub(crate) fn pop(&mut self) -> Option<(u64, u32)> {
            loop {
                if let Some(Reverse((k, _, v))) = self.heap.pop() {
                    return Some((k, v));
                }
                // move on to the next non-empty bucket
                loop {
                    self.cur += 1;
                    if self.cur >= self.buckets.len() {
                        return None;
                    }
                    if !self.buckets[self.cur].is_empty() {
                        break;
                    }
                }
                let items = std::mem::take(&mut self.buckets[self.cur]);
                let old = std::mem::replace(&mut self.heap, BinaryHeap::from(items));
                // keep the drained heap's allocation for a later bucket
                let mut spare = old.into_vec();
                spare.clear();
                if let Some(next) = self.buckets.get_mut(self.cur + 1)
                    && next.capacity() < spare.capacity()
                {
                    spare.append(next);
                    *next = spare;
                }
            }
        }
    }

    /// Floods `relief` from `seeds` (Algorithm WS of spec 004 §2.5). `seeds.labels` gives the seed
    /// label of each seed pixel (0 elsewhere) and `seeds.minima` the seed records, copied into the
    /// result.
    ///
    /// Errors: empty relief, NaN/infinite values, size mismatch between relief and seeds, seed
    /// labels outside 1..=K, no seed at all.
    pub(crate) fn flood_reference<T: Relief>(
        relief: &Plane<T>,
        seeds: &Minima,
        options: WatershedOptions,
    ) -> Result<Segmentation, VisionError> {
        super::check_flood_input(relief, seeds)?;
        let (w, h) = (relief.width as usize, relief.height as usize);
        let d = &relief.data;
        let mut labels = seeds.labels.data.clone();
        // Seeds are pushed in raster order (the FIFO tie rule then serves equal seeds in raster
        // order).
        let (vmin, vmax) = d
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                let v = v.to_f64();
                (lo.min(v), hi.max(v))
            });
        let mut heap = BucketQueue::new(vmin, vmax, d.len());
        for (p, &l) in labels.iter().enumerate() {
            if l != 0 {
                let v = d[p].to_f64();
                heap.push(v, level_key(v), p as u32);
            }
        }
        let offs = options.connectivity.offsets();
        while let Some((level, p)) = heap.pop() {
            let p = p as usize;
            let lab = labels[p];
            let (x, y) = (p % w, p / w);
            let interior = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
            for &(dx, dy) in offs {
                let (qx, qy) = (x as isize + dx as isize, y as isize + dy as isize);
                if !interior && (qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize) {
                    continue;
                }
                let q = qy as usize * w + qx as usize;
                if labels[q] == 0 {
                    labels[q] = lab;
                    let vq = d[q].to_f64();
                    let kq = level_key(vq);
                    if kq > level {
                        heap.push(vq, kq, q as u32);
                    } else {
                        heap.push(key_level(level), level, q as u32);
                    }
                }
            }
        }
        Ok(Segmentation {
            labels: Plane {
                width: relief.width,
                height: relief.height,
                data: labels,
            },
            minima: seeds.minima.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use reference::BucketQueue;
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;

    /// The row codes are the same in every build the CPU supports (baseline, AVX2, AVX-512F),
    /// 4- and 8-neighbour, with many ties (few grey levels) and with distinct values.
    #[test]
    fn code_rows_agree_across_isa_builds() {
        let levels = crate::simd::Isa::all_supported();
        let mut seed = 7u32;
        for levels_of_grey in [3u32, 1 << 20] {
            for l in [1usize, 5, 16, 17, 63, 200] {
                let mut rows: Vec<Vec<f64>> = Vec::new();
                for _ in 0..9 {
                    rows.push(
                        (0..l)
                            .map(|_| {
                                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                                f64::from((seed >> 8) % levels_of_grey)
                            })
                            .collect(),
                    );
                }
                let run = |level| {
                    let mut scratch = RowScratch {
                        min: vec![0.0; l],
                        mask: vec![0; l],
                    };
                    let mut out8 = vec![0u8; l];
                    let nb8: [&[f64]; 8] = std::array::from_fn(|i| rows[i + 1].as_slice());
                    code_row(level, &rows[0], nb8, &mut out8, &mut scratch);
                    let mut out4 = vec![0u8; l];
                    let nb4: [&[f64]; 4] = std::array::from_fn(|i| rows[i + 1].as_slice());
                    code_row(level, &rows[0], nb4, &mut out4, &mut scratch);
                    (out8, out4)
                };
                let want = run(levels[0]);
                for &level in &levels[1..] {
                    assert_eq!(
                        run(level),
                        want,
                        "{l} columns, {levels_of_grey} levels, {level:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn level_key_is_monotone() {
        let vals = [-1e300, -2.5, -0.0, 0.0, 1e-300, 0.5, 1.0, 253.0, 1e300];
        for w in vals.windows(2) {
            assert!(level_key(w[0]) <= level_key(w[1]), "{w:?}");
        }
        assert!(level_key(-1.0) < level_key(1.0));
    }

    #[test]
    fn bucket_queue_matches_binary_heap() {
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(7);
        let mut q = BucketQueue::new(0.0, 1000.0, 4000);
        let mut bh = BinaryHeap::new();
        let mut last = 0.0f64;
        let mut popped = 0;
        for i in 0..20000u32 {
            // many equal levels (FIFO must hold), tiny and large steps
            let level = match rng.next_u32() % 4 {
                0 => last,
                1 => last + f64::from(rng.next_u32() % 4) * 1e-9,
                2 => last + f64::from(rng.next_u32() % 1000) * 1e-3,
                _ => (last + f64::from(rng.next_u32() % 1000) * 0.01).min(1000.0),
            };
            q.push(level, level_key(level), i);
            bh.push(Reverse((level_key(level), u64::from(i), i)));
            if rng.next_u32().is_multiple_of(2) {
                let a = q.pop().unwrap();
                let Reverse(b) = bh.pop().unwrap();
                assert_eq!(a, (b.0, b.2));
                last = key_level(a.0);
                popped += 1;
            }
        }
        while let Some(a) = q.pop() {
            let Reverse(b) = bh.pop().unwrap();
            assert_eq!(a, (b.0, b.2));
        }
        assert!(bh.is_empty());
        assert!(popped > 5000);
        for v in [-3.5, -0.0, 0.0, 1e-300, 2.0, 253.01] {
            assert_eq!(key_level(level_key(v)).to_bits(), f64::to_bits(v));
        }
    }

    /// The presorted flood reproduces the priority-queue flood exactly: random reliefs with few
    /// distinct values (large plateaus and many equal levels), both connectivities, seeds from
    /// the regional minima and arbitrary seeds (which make the flood descend into the FIFO).
    #[test]
    fn presorted_flood_equals_priority_queue_flood() {
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(11);
        for case in 0..300u32 {
            let w = 1 + rng.next_u32() % 23;
            let h = 1 + rng.next_u32() % 17;
            let levels = 1 + rng.next_u32() % (if case % 3 == 0 { 3 } else { 40 });
            let relief =
                Plane::from_fn(w, h, |_, _| f64::from(rng.next_u32() % levels) * 0.25 - 2.0);
            for conn in [Connectivity::Four, Connectivity::Eight] {
                let opts = WatershedOptions { connectivity: conn };
                let minima = regional_minima(&relief, conn).unwrap();
                let a = flood(&relief, &minima, opts).unwrap();
                let b = reference::flood_reference(&relief, &minima, opts).unwrap();
                assert_eq!(a, b, "case {case} minima seeds {w}x{h} {conn:?}");
                // arbitrary seeds: a few random pixels with random labels
                let k = 1 + rng.next_u32() % 5;
                let mut labels = Plane::new(w, h, 0u32);
                for id in 1..=k {
                    let (x, y) = (rng.next_u32() % w, rng.next_u32() % h);
                    labels.set(x, y, id);
                }
                let seeds = Minima {
                    labels,
                    minima: minima
                        .minima
                        .iter()
                        .copied()
                        .cycle()
                        .take(k as usize)
                        .collect(),
                };
                let a = flood(&relief, &seeds, opts).unwrap();
                let b = reference::flood_reference(&relief, &seeds, opts).unwrap();
                assert_eq!(a, b, "case {case} random seeds {w}x{h} {conn:?}");
                let r32 = relief.map(|&v| v as f32);
                let a = flood(&r32, &seeds, opts).unwrap();
                let b = reference::flood_reference(&r32, &seeds, opts).unwrap();
                assert_eq!(a, b, "case {case} f32 {w}x{h} {conn:?}");
            }
        }
    }

    /// The descent flood itself (not the fallback) reproduces the priority-queue flood: it must
    /// succeed whenever every regional minimum holds a seed, and agree with the reference
    /// whenever it succeeds (random seeds usually leave a minimum unseeded and make it give up).
    /// Reliefs with few levels (plateaus, ties among lowest neighbours, plateau components
    /// touching the same entries) and with many levels.
    #[test]
    fn descent_flood_equals_priority_queue_flood() {
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(23);
        let (mut random_seed_runs, mut plateau_cases, mut fused_runs) = (0, 0, 0);
        for case in 0..400u32 {
            let w = 1 + rng.next_u32() % 29;
            let h = 1 + rng.next_u32() % 19;
            let levels = match case % 4 {
                0 => 2,
                1 => 3,
                2 => 12,
                _ => 5000,
            };
            let relief = Plane::from_fn(w, h, |_, _| f64::from(rng.next_u32() % levels) - 7.0);
            for conn in [Connectivity::Four, Connectivity::Eight] {
                let opts = WatershedOptions { connectivity: conn };
                let minima = regional_minima(&relief, conn).unwrap();
                let b = reference::flood_reference(&relief, &minima, opts).unwrap();
                let mut labels = minima.labels.data.clone();
                assert!(
                    flood_descent(&relief.data, w as usize, &mut labels, conn).is_ok(),
                    "case {case} {conn:?}: descent gave up with every minimum seeded"
                );
                assert_eq!(labels, b.labels.data, "case {case} {w}x{h} {conn:?}");
                // `None`: a plateau without a lower neighbour somewhere (the general path)
                if let Some(s) = segment_descent(&relief, conn) {
                    fused_runs += 1;
                    assert_eq!(s, b, "case {case} fused minima {conn:?}");
                }
                assert_eq!(watershed(&relief, opts).unwrap(), b);
                if minima.minima.iter().any(|m| m.size > 1) {
                    plateau_cases += 1;
                }
                // random extra seeds on top of the minima (the shortcut must still hold), and
                // random seeds alone
                let mut extra = minima.clone();
                let mut alone = Minima {
                    labels: Plane::new(w, h, 0u32),
                    minima: minima.minima.clone(),
                };
                for _ in 0..=(rng.next_u32() % 6) {
                    let (x, y) = (rng.next_u32() % w, rng.next_u32() % h);
                    let id = 1 + rng.next_u32() % minima.len() as u32;
                    extra.labels.set(x, y, id);
                    alone.labels.set(x, y, id);
                }
                for seeds in [&extra, &alone] {
                    let b = reference::flood_reference(&relief, seeds, opts).unwrap();
                    let mut labels = seeds.labels.data.clone();
                    if flood_descent(&relief.data, w as usize, &mut labels, conn).is_ok() {
                        random_seed_runs += 1;
                        assert_eq!(labels, b.labels.data, "case {case} extra seeds {conn:?}");
                    } else {
                        assert_eq!(labels, seeds.labels.data, "left the seeds as they were");
                    }
                    assert_eq!(flood(&relief, seeds, opts).unwrap(), b);
                }
            }
        }
        assert!(random_seed_runs > 400, "{random_seed_runs}");
        assert!(plateau_cases > 100, "{plateau_cases}");
        assert!(fused_runs > 100, "{fused_runs}");
    }

    /// `-0.0` next to `0.0` (equal for `==`, ordered by `total_cmp`): the descent flood declines
    /// and the result still equals the reference.
    #[test]
    fn negative_zero_falls_back_to_the_reference_order() {
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(5);
        for case in 0..60 {
            let relief: Plane<f64> = Plane::from_fn(9, 7, |_, _| match rng.next_u32() % 4 {
                0 => -0.0,
                1 => 0.0,
                2 => 1.0,
                _ => -1.0,
            });
            let mut labels = Plane::new(9, 7, 0u32);
            labels.set(rng.next_u32() % 9, rng.next_u32() % 7, 1);
            labels.set(rng.next_u32() % 9, rng.next_u32() % 7, 2);
            let seeds = Minima {
                labels,
                minima: regional_minima(&relief, Connectivity::Eight)
                    .unwrap()
                    .minima
                    .into_iter()
                    .cycle()
                    .take(2)
                    .collect(),
            };
            let mut l = seeds.labels.data.clone();
            if relief
                .data
                .iter()
                .any(|v: &f64| v.to_bits() == (-0.0f64).to_bits())
            {
                assert!(flood_descent(&relief.data, 9, &mut l, Connectivity::Eight).is_err());
            }
            for conn in [Connectivity::Four, Connectivity::Eight] {
                let opts = WatershedOptions { connectivity: conn };
                let b = reference::flood_reference(&relief, &seeds, opts).unwrap();
                assert_eq!(flood(&relief, &seeds, opts).unwrap(), b, "case {case}");
            }
        }
    }

    #[test]
    fn two_dips_split_at_ridge() {
        // two Gaussian dips at x = 10 and x = 30 of a 41x15 image: ridge at x = 20
        let p = Plane::from_fn(41, 15, |x, y| {
            let (xf, yf) = (f64::from(x), f64::from(y));
            let g = |cx: f64| (-((xf - cx).powi(2) + (yf - 7.0).powi(2)) / 50.0).exp();
            -(g(10.0) + g(30.0)) + 1e-3 * yf
        });
        let s = watershed(&p, WatershedOptions::default()).unwrap();
        assert_eq!(s.n_regions(), 2);
        for y in 0..15 {
            for x in 0..41 {
                let l = *s.labels.get(x, y).unwrap();
                if x < 20 {
                    assert_eq!(l, 1, "({x},{y})");
                } else if x > 20 {
                    assert_eq!(l, 2, "({x},{y})");
                }
            }
        }
    }

    #[test]
    fn errors() {
        let p = Plane::new(4, 4, 1.0f64);
        let seeds = Minima {
            labels: Plane::new(3, 4, 0),
            minima: vec![],
        };
        assert!(matches!(
            flood(&p, &seeds, WatershedOptions::default()),
            Err(VisionError::SizeMismatch { .. })
        ));
        let seeds = Minima {
            labels: Plane::new(4, 4, 0),
            minima: vec![],
        };
        assert!(flood(&p, &seeds, WatershedOptions::default()).is_err());
    }

    #[test]
    fn boundary() {
        let l = Plane::from_vec(3, 1, vec![1u32, 1, 2]).unwrap();
        assert_eq!(boundary_mask(&l).data, vec![false, true, true]);
    }
}
