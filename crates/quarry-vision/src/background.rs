//! A running background model for a static camera: the per-pixel **median of sampled frames**
//! (a temporal median filter, Cucchiara et al. 2003; Lo & Velastin 2001), and the foreground
//! mask `|I − B| > τ`.
//!
//! Every `every`-th frame is kept as a sample in a ring of `samples` frames; the background is
//! the per-pixel median of the samples held (the lower median while the ring is filling). A
//! person covering a pixel in fewer than half of the samples does not enter the background, so
//! with a ring spanning `samples · every` frames, anyone who crosses a pixel in less than about
//! half that time stays foreground. The median is recomputed only when a sample arrives, with
//! a branch-free sorting network over blocks of pixels (the compiler vectorises the min/max).
//!
//! ```
//! use quarry_core::Plane;
//! use quarry_vision::background::{MedianBackground, MedianBackgroundParams};
//! let mut bg = MedianBackground::new(MedianBackgroundParams { samples: 5, every: 2, threshold: 20 })?;
//! // a grey floor with a dark 4x4 square walking right, 3 px per frame
//! for t in 0..20u32 {
//!     let f = Plane::from_fn(64, 16, |x, y| if (6..10).contains(&y) && x / 4 == t * 3 / 4 { 40u8 } else { 150 });
//!     bg.update(&f)?;
//! }
//! assert!(bg.background().data.iter().all(|&v| v == 150));
//! let now = Plane::from_fn(64, 16, |x, _| if x < 4 { 40u8 } else { 150 });
//! let fg = bg.foreground(&now)?;
//! assert_eq!(fg.data.iter().filter(|&&m| m).count(), 4 * 16);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use quarry_core::{CoreError, Plane};

/// Largest number of samples in the ring.
pub const MAX_SAMPLES: usize = 63;

/// Parameters of [`MedianBackground`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MedianBackgroundParams {
    /// Samples in the ring (odd, 1..=63).
    pub samples: usize,
    /// Keep one frame in `every` as a sample (>= 1).
    pub every: usize,
    /// A pixel is foreground when `|I − B| > threshold` (grey levels).
    pub threshold: u8,
}

impl MedianBackgroundParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<(), VisionError> {
        if self.samples == 0 || self.samples.is_multiple_of(2) || self.samples > MAX_SAMPLES {
            return Err(CoreError::invalid(
                "samples",
                format!("must be odd and in 1..={MAX_SAMPLES}, got {}", self.samples),
            )
            .into());
        }
        if self.every == 0 {
            return Err(CoreError::invalid("every", "must be >= 1").into());
        }
        Ok(())
    }
}

/// Per-pixel temporal median of sampled frames (see the module docs).
#[derive(Debug, Clone)]
pub struct MedianBackground {
    params: MedianBackgroundParams,
    width: u32,
    height: u32,
    /// The ring of samples, each a full frame.
    ring: Vec<Vec<u8>>,
    /// Where the next sample goes.
    next: usize,
    frames: u64,
    background: Plane<u8>,
}

/// Pixels per block of the median (the samples of one block stay in L1).
const BLOCK: usize = 512;

impl MedianBackground {
    /// An empty model. Errors: invalid parameters.
    pub fn new(params: MedianBackgroundParams) -> Result<Self, VisionError> {
        params.validate()?;
        Ok(Self {
            params,
            width: 0,
            height: 0,
            ring: Vec::new(),
            next: 0,
            frames: 0,
            background: Plane {
                width: 0,
                height: 0,
                data: Vec::new(),
            },
        })
    }

    /// The parameters.
    pub fn params(&self) -> &MedianBackgroundParams {
        &self.params
    }

    /// Samples held so far (at most `samples`).
    pub fn samples_held(&self) -> usize {
        self.ring.len()
    }

    /// Frames seen so far.
    pub fn frames_seen(&self) -> u64 {
        self.frames
    }

    /// The current background (empty before the first frame).
    pub fn background(&self) -> &Plane<u8> {
        &self.background
    }

    /// Whether the next [`update`](Self::update) takes a sample.
    pub fn sample_due(&self) -> bool {
        self.frames.is_multiple_of(self.params.every as u64)
    }

    /// Feeds one frame; every `every`-th frame (the first included) becomes a sample and the
    /// median is recomputed.
    ///
    /// Errors: an empty frame, a frame whose data do not match its size, or a frame of another
    /// size than the first.
    pub fn update(&mut self, frame: &Plane<u8>) -> Result<(), VisionError> {
        self.begin(frame)?;
        if self.sample_due() {
            self.push_sample(&frame.data);
        }
        self.frames += 1;
        Ok(())
    }

    /// [`update`](Self::update) with a *selective* sample: where `hold` is true the sample takes
    /// the current background instead of the frame (a tracked person who stands still does not
    /// become background). Before the first frame `hold` is ignored.
    ///
    /// Errors: as [`update`](Self::update), and a `hold` mask of another size than the frame.
    pub fn update_selective(
        &mut self,
        frame: &Plane<u8>,
        hold: &Plane<bool>,
    ) -> Result<(), VisionError> {
        self.begin(frame)?;
        if hold.dimensions() != frame.dimensions() || hold.data.len() != frame.data.len() {
            return Err(VisionError::SizeMismatch {
                what: "background model hold mask",
                a: frame.dimensions(),
                b: hold.dimensions(),
            });
        }
        if self.sample_due() {
            if self.frames == 0 {
                self.push_sample(&frame.data);
            } else {
                let sample: Vec<u8> = frame
                    .data
                    .iter()
                    .zip(&hold.data)
                    .zip(&self.background.data)
                    .map(|((&f, &h), &b)| if h { b } else { f })
                    .collect();
                self.push_sample(&sample);
            }
        }
        self.frames += 1;
        Ok(())
    }

    /// Checks `frame` and records the sequence's size on the first frame.
    fn begin(&mut self, frame: &Plane<u8>) -> Result<(), VisionError> {
        self.check(frame)?;
        if self.frames == 0 {
            self.width = frame.width;
            self.height = frame.height;
        }
        Ok(())
    }

    /// Stores a sample (of the checked frame size) and recomputes the median.
    fn push_sample(&mut self, data: &[u8]) {
        if self.ring.len() < self.params.samples {
            self.ring.push(data.to_vec());
        } else {
            self.ring[self.next].copy_from_slice(data);
        }
        self.next = (self.next + 1) % self.params.samples;
        self.background = Plane {
            width: self.width,
            height: self.height,
            data: median_of(&self.ring),
        };
    }

    /// The foreground mask of `frame` against the current background: `|I − B| > threshold`.
    ///
    /// Errors: as [`update`](Self::update), and a call before the first update.
    pub fn foreground(&self, frame: &Plane<u8>) -> Result<Plane<bool>, VisionError> {
        if self.frames == 0 {
            return Err(CoreError::invalid("background", "no frame seen yet").into());
        }
        self.check(frame)?;
        let t = self.params.threshold;
        let data = frame
            .data
            .iter()
            .zip(&self.background.data)
            .map(|(&a, &b)| a.abs_diff(b) > t)
            .collect();
        Ok(Plane {
            width: frame.width,
            height: frame.height,
            data,
        })
    }

    fn check(&self, frame: &Plane<u8>) -> Result<(), VisionError> {
        if frame.width == 0 || frame.height == 0 {
            return Err(VisionError::EmptyImage {
                what: "background model",
                width: frame.width,
                height: frame.height,
                min: 1,
            });
        }
        quarry_core::ensure_len(
            frame.data.len(),
            frame.width as usize * frame.height as usize,
            "background model frame data",
        )?;
        if self.frames > 0 && (frame.width, frame.height) != (self.width, self.height) {
            return Err(VisionError::SizeMismatch {
                what: "background model",
                a: (self.width, self.height),
                b: (frame.width, frame.height),
            });
        }
        Ok(())
    }
}

/// Per-pixel (lower) median of equally long sample frames: element `(n − 1) / 2` of the sorted
/// values. Odd-even transposition sort per block (n rounds of compare-exchange on whole rows of
/// a block).
fn median_of(ring: &[Vec<u8>]) -> Vec<u8> {
    let n = ring.len();
    let len = ring.first().map_or(0, Vec::len);
    let mut out = vec![0u8; len];
    if n == 0 {
        return out;
    }
    let mut rows = vec![[0u8; BLOCK]; n];
    let mut start = 0;
    while start < len {
        let m = BLOCK.min(len - start);
        for (r, s) in rows.iter_mut().zip(ring) {
            r[..m].copy_from_slice(&s[start..start + m]);
        }
        for round in 0..n {
            let mut i = round % 2;
            while i + 1 < n {
                let (lo, hi) = rows.split_at_mut(i + 1);
                let (a, b) = (&mut lo[i], &mut hi[0]);
                for (x, y) in a.iter_mut().zip(b.iter_mut()) {
                    let (mn, mx) = ((*x).min(*y), (*x).max(*y));
                    *x = mn;
                    *y = mx;
                }
                i += 2;
            }
        }
        out[start..start + m].copy_from_slice(&rows[(n - 1) / 2][..m]);
        start += m;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn params(samples: usize, every: usize) -> MedianBackgroundParams {
        MedianBackgroundParams {
            samples,
            every,
            threshold: 20,
        }
    }

    #[test]
    fn invalid_parameters_are_refused() {
        for (s, e) in [(0, 1), (4, 1), (65, 1), (3, 0)] {
            assert!(MedianBackground::new(params(s, e)).is_err(), "{s} {e}");
        }
    }

    #[test]
    fn bad_frames_are_errors() {
        let mut bg = MedianBackground::new(params(3, 1)).unwrap();
        assert!(bg.foreground(&Plane::new(4, 4, 0u8)).is_err());
        assert!(bg.update(&Plane::new(0, 4, 0u8)).is_err());
        let bad = Plane {
            width: 3,
            height: 3,
            data: vec![0u8; 5],
        };
        assert!(bg.update(&bad).is_err());
        bg.update(&Plane::new(4, 4, 0u8)).unwrap();
        let e = bg.update(&Plane::new(5, 4, 0u8)).unwrap_err().to_string();
        assert!(e.contains("background"), "{e}");
        assert!(bg.foreground(&Plane::new(4, 5, 0u8)).is_err());
    }

    #[test]
    fn samples_every_kth_frame_and_a_brief_visitor_never_enters() {
        let mut bg = MedianBackground::new(params(5, 3)).unwrap();
        // a bright visitor on pixel 0 for frames 3..=5 (one sample: frame 3) and a dark one
        // on pixel 1 for frames 6..=12 (samples 6, 9, 12: three of five once the ring is full)
        for t in 0..15u32 {
            let f = Plane::from_fn(2, 1, |x, _| match x {
                0 if (3..=5).contains(&t) => 250u8,
                1 if (6..=12).contains(&t) => 10,
                _ => 100,
            });
            bg.update(&f).unwrap();
        }
        assert_eq!(bg.samples_held(), 5);
        assert_eq!(bg.frames_seen(), 15);
        // samples: frames 0, 3, 6, 9, 12 → pixel 0: 100 250 100 100 100 → 100;
        // pixel 1: 100 100 10 10 10 → 10 (a visitor in most samples is background)
        assert_eq!(bg.background().data, vec![100, 10]);
    }

    #[test]
    fn a_held_pixel_keeps_the_background() {
        let mut bg = MedianBackground::new(params(3, 1)).unwrap();
        let grey = Plane::new(2, 1, 100u8);
        bg.update(&grey).unwrap();
        // a visitor stands on pixel 0 for 5 frames; held there, it never enters the samples
        let visitor = Plane {
            width: 2,
            height: 1,
            data: vec![10, 100],
        };
        let hold = Plane {
            width: 2,
            height: 1,
            data: vec![true, false],
        };
        for _ in 0..5 {
            bg.update_selective(&visitor, &hold).unwrap();
        }
        assert_eq!(bg.background().data, vec![100, 100]);
        // without the hold it becomes background
        for _ in 0..3 {
            bg.update(&visitor).unwrap();
        }
        assert_eq!(bg.background().data, vec![10, 100]);
        let small = Plane::new(1, 1, false);
        assert!(bg.update_selective(&visitor, &small).is_err());
    }

    #[test]
    fn foreground_is_the_strict_threshold_of_the_difference() {
        let mut bg = MedianBackground::new(params(1, 1)).unwrap();
        bg.update(&Plane::new(4, 1, 100u8)).unwrap();
        let f = Plane {
            width: 4,
            height: 1,
            data: vec![120, 121, 80, 79],
        };
        assert_eq!(
            bg.foreground(&f).unwrap().data,
            vec![false, true, false, true]
        );
    }

    proptest! {
        #[test]
        fn median_matches_sorting(
            samples in prop::collection::vec(prop::collection::vec(any::<u8>(), 700), 1..12)
        ) {
            let m = median_of(&samples);
            for (p, &got) in m.iter().enumerate() {
                let mut v: Vec<u8> = samples.iter().map(|s| s[p]).collect();
                v.sort_unstable();
                prop_assert_eq!(got, v[(v.len() - 1) / 2]);
            }
        }
    }
}
