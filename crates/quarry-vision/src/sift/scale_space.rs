//! The Gaussian scale space of SIFT: the optional bilinear ×2 up-sampling of the input, the
//! initial blur, `s + 3` Gaussian images per octave (incremental σ as OpenCV's
//! `buildGaussianPyramid`, blurred by [`super::fast`]) and decimation by 2 to the next octave.
//! DoG images are not stored (see [`ScaleSpace::dog`]).

use super::{SiftParams, fast};
use crate::VisionError;
use quarry_core::Plane;

#[cfg(feature = "parallel")]
use rayon::prelude::*;

/// One octave of the scale space: `s + 3` Gaussian images. The `s + 2` DoG images are not
/// stored: every DoG value is computed where it is used as `G[l + 1] − G[l]` (the same single
/// subtraction, so the values are those of stored DoG images), which saves allocating and
/// writing 5 images per octave.
#[derive(Debug, Clone)]
pub(super) struct Octave {
    pub(super) gauss: Vec<Plane<f32>>,
}

/// The Gaussian and difference-of-Gaussian pyramids of one image.
#[derive(Debug, Clone)]
pub struct ScaleSpace {
    pub(super) octaves: Vec<Octave>,
    pub(super) first_octave: i32,
    pub(super) layers: usize,
}

impl ScaleSpace {
    /// Number of octaves.
    pub fn n_octaves(&self) -> usize {
        self.octaves.len()
    }

    /// Index of the first octave (−1 when up-sampled).
    pub fn first_octave(&self) -> i32 {
        self.first_octave
    }

    /// Gaussian image `layer` (0..s+3) of `octave` (counted from [`Self::first_octave`]).
    pub fn gaussian(&self, octave: i32, layer: usize) -> Option<&Plane<f32>> {
        let o = usize::try_from(octave - self.first_octave).ok()?;
        self.octaves.get(o)?.gauss.get(layer)
    }

    /// DoG image `layer` (0..s+2) of `octave`: `G[layer + 1] − G[layer]` (computed on request;
    /// the scale space does not store DoG images).
    pub fn dog(&self, octave: i32, layer: usize) -> Option<Plane<f32>> {
        let o = usize::try_from(octave - self.first_octave).ok()?;
        let g = &self.octaves.get(o)?.gauss;
        Some(sub_planes(g.get(layer + 1)?, g.get(layer)?))
    }
}

/// Bilinear ×2 up-sampling with pixel-centre alignment (OpenCV `resize`, `INTER_LINEAR`).
fn upsample2(src: &Plane<f32>) -> Plane<f32> {
    let (w, h) = (src.width as usize, src.height as usize);
    let (w2, h2) = (2 * w, 2 * h);
    // Source index and weight of the second tap for output coordinate i of a side of n pixels.
    let taps = |n: usize, n2: usize| -> Vec<(usize, usize, f32)> {
        (0..n2)
            .map(|i| {
                let f = (i as f32 + 0.5) * 0.5 - 0.5;
                let s = f.floor();
                let mut frac = f - s;
                let mut s = s as isize;
                if s < 0 {
                    s = 0;
                    frac = 0.0;
                }
                let s = s as usize;
                if s >= n - 1 {
                    (n - 1, n - 1, 0.0)
                } else {
                    (s, s + 1, frac)
                }
            })
            .collect()
    };
    let tx = taps(w, w2);
    let ty = taps(h, h2);
    // Horizontal pass for each source row, then vertical interpolation.
    // Both passes are row-parallel with `parallel` (each output value is computed alone).
    let mut hrows = vec![0f32; w2 * h];
    let h_row = |(y, out): (usize, &mut [f32])| {
        let row = &src.data[y * w..(y + 1) * w];
        for (o, &(a, b, f)) in out.iter_mut().zip(&tx) {
            *o = row[a] * (1.0 - f) + row[b] * f;
        }
    };
    let mut data = vec![0f32; w2 * h2];
    let v_row = |hrows: &[f32], (out, &(a, b, f)): (&mut [f32], &(usize, usize, f32))| {
        let ra = &hrows[a * w2..(a + 1) * w2];
        let rb = &hrows[b * w2..(b + 1) * w2];
        for ((o, &va), &vb) in out.iter_mut().zip(ra).zip(rb) {
            *o = va * (1.0 - f) + vb * f;
        }
    };
    #[cfg(feature = "parallel")]
    {
        hrows
            .par_chunks_mut(w2)
            .enumerate()
            .with_min_len(16)
            .for_each(h_row);
        data.par_chunks_mut(w2)
            .zip(ty.par_iter())
            .with_min_len(16)
            .for_each(|x| v_row(&hrows, x));
    }
    #[cfg(not(feature = "parallel"))]
    {
        hrows.chunks_mut(w2).enumerate().for_each(h_row);
        data.chunks_mut(w2)
            .zip(ty.iter())
            .for_each(|x| v_row(&hrows, x));
    }
    Plane {
        width: w2 as u32,
        height: h2 as u32,
        data,
    }
}

/// Decimation by 2: pixel (x, y) ← (2x, 2y).
fn downsample2(src: &Plane<f32>) -> Plane<f32> {
    let (w, h) = (src.width as usize, src.height as usize);
    let (w2, h2) = (w / 2, h / 2);
    let mut data = Vec::with_capacity(w2 * h2);
    for y in 0..h2 {
        let row = &src.data[2 * y * w..2 * y * w + w];
        data.extend(row.iter().step_by(2).take(w2));
    }
    Plane {
        width: w2 as u32,
        height: h2 as u32,
        data,
    }
}

/// Gaussian blur of the scale space: bit-identical to [`crate::blur::gaussian_blur_f32`]
/// (OpenCV's kernel size rule, reflect-101), laid out for speed in [`fast`].
fn blur(src: &Plane<f32>, sigma: f64, tmp: &mut Vec<f32>) -> Result<Plane<f32>, VisionError> {
    Ok(fast::blur(src, &fast::half_kernel(sigma)?, tmp))
}

fn sub_planes(a: &Plane<f32>, b: &Plane<f32>) -> Plane<f32> {
    Plane {
        width: a.width,
        height: a.height,
        data: a.data.iter().zip(&b.data).map(|(x, y)| x - y).collect(),
    }
}

pub(super) fn build_scale_space(
    img: &Plane<f32>,
    p: &SiftParams,
) -> Result<ScaleSpace, VisionError> {
    let s = p.n_octave_layers as usize;
    let sigma = p.sigma as f32;
    let sin = p.input_blur as f32;
    // Scratch of the horizontal blur pass, shared by every blur of the pyramid.
    let mut tmp = Vec::new();
    let (base, first_octave) = if p.upsample {
        let sig_diff = (sigma * sigma - sin * sin * 4.0).max(0.01).sqrt();
        (blur(&upsample2(img), f64::from(sig_diff), &mut tmp)?, -1)
    } else {
        let sig_diff = (sigma * sigma - sin * sin).max(0.01).sqrt();
        (blur(img, f64::from(sig_diff), &mut tmp)?, 0)
    };
    let min_side = f64::from(base.width.min(base.height));
    let n_oct = ((min_side.log2() - 2.0).round_ties_even() as i32 - first_octave).max(1) as usize;

    // Incremental sigmas (OpenCV's buildGaussianPyramid, in f64).
    let mut sig = vec![p.sigma; s + 3];
    let k = 2f64.powf(1.0 / s as f64);
    for (i, si) in sig.iter_mut().enumerate().skip(1) {
        let prev = k.powi(i as i32 - 1) * p.sigma;
        let total = prev * k;
        *si = (total * total - prev * prev).sqrt();
    }

    let kernels = sig[1..]
        .iter()
        .map(|&si| fast::half_kernel(si))
        .collect::<Result<Vec<_>, _>>()?;
    let mut octaves: Vec<Octave> = Vec::with_capacity(n_oct);
    let mut next_base = Some(base);
    for _ in 0..n_oct {
        let g0 = match next_base.take() {
            Some(b) => b,
            None => match octaves.last() {
                Some(prev) => downsample2(&prev.gauss[s]),
                None => break,
            },
        };
        if g0.width < 2 || g0.height < 2 {
            break;
        }
        let mut gauss = Vec::with_capacity(s + 3);
        gauss.push(g0);
        for k in &kernels {
            let next = fast::blur(&gauss[gauss.len() - 1], k, &mut tmp);
            gauss.push(next);
        }
        octaves.push(Octave { gauss });
    }
    Ok(ScaleSpace {
        octaves,
        first_octave,
        layers: s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upsample_is_centre_aligned() {
        let src = Plane::from_vec(2, 1, vec![0.0f32, 4.0]).unwrap();
        let up = upsample2(&src);
        assert_eq!((up.width, up.height), (4, 2));
        assert_eq!(&up.data[..4], &[0.0, 1.0, 3.0, 4.0]);
    }

    #[test]
    fn downsample_takes_even_pixels() {
        let src = Plane::from_fn(5, 5, |x, y| (x + 10 * y) as f32);
        let d = downsample2(&src);
        assert_eq!((d.width, d.height), (2, 2));
        assert_eq!(d.data, vec![0.0, 2.0, 20.0, 22.0]);
    }
}
