//! The whole segmentation step of spec 004: ramp (1)(2) → f64 Gaussian blur σ → regional minima
//! → Meyer watershed.

use crate::VisionError;
use crate::blur::{Border, GaussianKernel, blur_rows};
use crate::minima::{Connectivity, regional_minima};
use crate::ramp::{checked_coefficients, ramp_axes, ramp_row};
use crate::watershed::{WatershedOptions, flood_minima, segment_descent};
use quarry_core::{CoreError, Plane, Segmentation, Segmenter};

/// Ramp + blur + watershed segmenter (implements [`Segmenter`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RampBlurWatershed {
    /// Blur σ in pixels (paper: 8.0; 5.0 for ~20-px people).
    pub sigma: f64,
    /// Grey levels L of the input (256 for 8-bit).
    pub levels: u32,
    /// Neighbourhood of minima and flooding.
    pub connectivity: Connectivity,
}

impl Default for RampBlurWatershed {
    fn default() -> Self {
        Self {
            sigma: 8.0,
            levels: 256,
            connectivity: Connectivity::Eight,
        }
    }
}

/// A segmentation together with the relief it was flooded on.
#[derive(Debug, Clone, PartialEq)]
pub struct SegmentOutput {
    /// The blurred ramped image B.
    pub relief: Plane<f64>,
    /// Labels and minima.
    pub segmentation: Segmentation,
}

impl RampBlurWatershed {
    /// A segmenter with blur `sigma` and the paper's other settings.
    pub fn new(sigma: f64) -> Self {
        Self {
            sigma,
            ..Self::default()
        }
    }

    /// The relief `B = blur_σ(I')` with `I'` the ramped frame (the ramp is fused into the blur's
    /// first pass; the values are bit-identical to
    /// `gaussian_blur_f64(&add_regular_ramp(frame, levels)?, sigma)`).
    ///
    /// Errors: frames smaller than 2×2, invalid σ, `levels <= 7` or pixels `>= levels`.
    pub fn relief(&self, frame: &Plane<u8>) -> Result<Plane<f64>, VisionError> {
        if frame.width < 2 || frame.height < 2 {
            return Err(VisionError::EmptyImage {
                what: "segmentation",
                width: frame.width,
                height: frame.height,
                min: 2,
            });
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(VisionError::InvalidSigma(self.sigma));
        }
        let (alpha, beta) = checked_coefficients(frame, self.levels, "segmentation")?;
        let kernel = GaussianKernel::new(self.sigma)?;
        let (w, h) = (frame.width as usize, frame.height as usize);
        let (gx, gy) = ramp_axes(w, h, beta);
        // the ramp is computed row by row inside the blur's horizontal pass: bit-identical to
        // `gaussian_blur_f64(&add_regular_ramp(frame, levels)?, sigma)` without the intermediate
        // image (tested)
        let data = blur_rows(
            w,
            h,
            |y, row: &mut [f64]| ramp_row(&frame.data[y * w..(y + 1) * w], alpha, &gx, gy[y], row),
            &kernel,
            Border::Reflect101,
        );
        Ok(Plane {
            width: frame.width,
            height: frame.height,
            data,
        })
    }

    /// Segments `frame` and keeps the relief.
    pub fn run(&self, frame: &Plane<u8>) -> Result<SegmentOutput, VisionError> {
        let relief = self.relief(frame)?;
        // one pass finds the minima and the labellers unless a minimum is a plateau
        let segmentation = if let Some(s) = segment_descent(&relief, self.connectivity) {
            s
        } else {
            let seeds = regional_minima(&relief, self.connectivity)?;
            flood_minima(
                &relief,
                seeds,
                WatershedOptions {
                    connectivity: self.connectivity,
                },
            )
        };
        Ok(SegmentOutput {
            relief,
            segmentation,
        })
    }
}

impl Segmenter for RampBlurWatershed {
    fn segment(&self, frame: &Plane<u8>) -> Result<Segmentation, CoreError> {
        self.run(frame).map(|o| o.segmentation).map_err(to_core)
    }
}

/// Maps a [`VisionError`] onto the shared error kinds (for the core traits).
fn to_core(e: VisionError) -> CoreError {
    match e {
        VisionError::Core(c) => c,
        VisionError::NonFinite(what) => CoreError::NonFinite { what },
        VisionError::EmptyImage { what, .. } => CoreError::Empty { what },
        VisionError::InvalidSigma(_) => CoreError::invalid("sigma", e.to_string()),
        other => CoreError::invalid("image", other.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_frame_has_one_region_seeded_top_left() {
        let s = RampBlurWatershed::new(2.0)
            .segment(&Plane::new(30, 20, 128u8))
            .unwrap();
        assert_eq!(s.n_regions(), 1);
        assert_eq!(s.minima[0].representative, (0, 0));
        assert!(s.labels.data.iter().all(|&l| l == 1));
    }

    #[test]
    fn two_dark_blobs_give_two_regions() {
        let f = Plane::from_fn(80, 40, |x, y| {
            let d1 = (x as i32 - 20).pow(2) + (y as i32 - 20).pow(2);
            let d2 = (x as i32 - 60).pow(2) + (y as i32 - 20).pow(2);
            if d1 < 64 || d2 < 64 { 20 } else { 200 }
        });
        let s = RampBlurWatershed::new(3.0).segment(&f).unwrap();
        let inner: Vec<_> = s
            .minima
            .iter()
            .filter(|m| {
                let (x, y) = m.representative;
                (x as i32 - 20).pow(2) + (y as i32 - 20).pow(2) < 16
                    || (x as i32 - 60).pow(2) + (y as i32 - 20).pow(2) < 16
            })
            .collect();
        assert_eq!(inner.len(), 2, "{:?}", s.minima);
        assert_ne!(s.labels.get(20, 20), s.labels.get(60, 20));
    }

    /// The optimised step (fused ramp, blocked blur, presorted flood) gives bit-identical
    /// reliefs and identical labels to the plain composition with the priority-queue flood, on
    /// the benchmark photo and on synthetic frames.
    #[cfg(feature = "io")]
    #[test]
    fn fast_step_equals_reference_composition() {
        use crate::blur::gaussian_blur_f64;
        use crate::ramp::add_regular_ramp;
        use crate::watershed::reference::flood_reference;
        let photo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/bench-data/photo_gray.png");
        let mut frames = vec![
            (
                "blobs",
                Plane::from_fn(97, 61, |x, y| ((x * x + 3 * y * y) % 251) as u8),
            ),
            ("flat", Plane::new(40, 40, 77u8)),
        ];
        if photo.exists() {
            frames.push(("photo_gray", crate::io::load_gray(&photo).unwrap()));
        } else {
            eprintln!("photo_gray part skipped: no {}", photo.display());
        }
        for (name, frame) in frames {
            let seg = RampBlurWatershed::default();
            let fast = seg.run(&frame).unwrap();
            let relief = gaussian_blur_f64(&add_regular_ramp(&frame, 256).unwrap(), 8.0).unwrap();
            assert!(
                fast.relief
                    .data
                    .iter()
                    .zip(&relief.data)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{name}: relief differs"
            );
            let seeds = regional_minima(&relief, Connectivity::Eight).unwrap();
            let reference = flood_reference(&relief, &seeds, WatershedOptions::default()).unwrap();
            assert_eq!(fast.segmentation, reference, "{name}: labels differ");
            assert!(fast.segmentation.n_regions() >= 1);
        }
    }

    /// FNV-1a digest of a label image (pins the exact labels across implementations).
    #[cfg(feature = "io")]
    fn label_digest(labels: &[u32]) -> u64 {
        labels.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &l| {
            l.to_le_bytes()
                .iter()
                .fold(h, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
        })
    }

    /// The labels of `photo_gray` (whole step, 8-connected; and the 4-connected watershed of the
    /// σ-8 f32 blur, the cv2/skimage benchmark workload) are pinned by digests taken from the
    /// priority-queue implementation (`watershed::reference`), so any change of the flood that
    /// alters a single label fails here.
    #[cfg(feature = "io")]
    #[test]
    fn photo_gray_label_digests() {
        use crate::blur::gaussian_blur_f32;
        use crate::watershed::flood;
        let photo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/bench-data/photo_gray.png");
        if !photo.exists() {
            eprintln!("skipped: no {}", photo.display());
            return;
        }
        let frame = crate::io::load_gray(&photo).unwrap();
        let seg = RampBlurWatershed::default().segment(&frame).unwrap();
        let blurred = gaussian_blur_f32(&frame.map(|&v| f32::from(v)), 8.0).unwrap();
        let seeds = regional_minima(&blurred, Connectivity::Four).unwrap();
        let four = flood(
            &blurred,
            &seeds,
            WatershedOptions {
                connectivity: Connectivity::Four,
            },
        )
        .unwrap();
        let got = (
            seg.n_regions(),
            label_digest(&seg.labels.data),
            four.n_regions(),
            label_digest(&four.labels.data),
        );
        eprintln!("photo_gray digests {got:#x?}");
        assert_eq!(got, (87, 0x71cb_07c9_608c_5132, 160, 0xe368_4d00_ae6f_a9ca));
    }

    #[test]
    fn bad_input() {
        let seg = RampBlurWatershed::default();
        assert!(matches!(
            seg.segment(&Plane::new(1, 1, 0u8)),
            Err(CoreError::Empty { .. })
        ));
        assert!(matches!(
            seg.segment(&Plane::new(0, 0, 0u8)),
            Err(CoreError::Empty { .. })
        ));
        assert!(matches!(
            RampBlurWatershed::new(0.0).segment(&Plane::new(4, 4, 0u8)),
            Err(CoreError::InvalidParameter { .. })
        ));
        assert!(
            RampBlurWatershed::new(-1.0)
                .run(&Plane::new(4, 4, 0u8))
                .is_err()
        );
    }
}
/// The fused path of [`RampBlurWatershed::run`] and [`crate::watershed::watershed`] (minima
/// from the descent pass) against regional minima + the priority-queue reference, on random
/// small frames (any grey-level count, σ 0.2–5.2, both connectivities) and raw reliefs with
/// plateaus.
#[cfg(test)]
mod fused_vs_reference {
    use super::*;
    use crate::watershed::reference::flood_reference;
    #[test]
    fn random_frames_and_reliefs() {
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(99);
        for case in 0..3000u32 {
            let w = 2 + rng.next_u32() % 30;
            let h = 2 + rng.next_u32() % 30;
            let lv = 1 + rng.next_u32() % 256;
            let frame = Plane::from_fn(w, h, |_, _| (rng.next_u32() % lv) as u8);
            let sigma = 0.2 + f64::from(rng.next_u32() % 100) / 20.0;
            let conn = if case % 2 == 0 {
                Connectivity::Eight
            } else {
                Connectivity::Four
            };
            let seg = RampBlurWatershed {
                sigma,
                levels: 256,
                connectivity: conn,
            };
            let fast = seg.run(&frame).unwrap();
            let seeds = regional_minima(&fast.relief, conn).unwrap();
            let r = flood_reference(
                &fast.relief,
                &seeds,
                WatershedOptions { connectivity: conn },
            )
            .unwrap();
            assert_eq!(fast.segmentation, r, "case {case}");
            // raw value images with few levels through watershed()
            let q = Plane::from_fn(w, h, |_, _| f64::from(rng.next_u32() % (1 + case % 7)));
            let s =
                crate::watershed::watershed(&q, WatershedOptions { connectivity: conn }).unwrap();
            let m = regional_minima(&q, conn).unwrap();
            let r = flood_reference(&q, &m, WatershedOptions { connectivity: conn }).unwrap();
            assert_eq!(s, r, "case {case} raw");
        }
    }
}
