//! The synthetic grey video `walkers-v1` of spec 004 §5.2 (watershed + SIFT pools tracker):
//! dark textured people-like blobs walking in straight lines over a static value-noise
//! background, with exact ground truth (MOT16/17 style, §5.4) and the scenario's events.
//!
//! - **Frames**: 800 × 450 u8 grey, 450 frames (`walkers-v1`), 200 for `walkers-v1-empty`.
//! - **Background** (static): 160 + 30·n(x, y), n a four-octave value noise (lattice spacing
//!   64, 32, 16, 8 px, weights 2^−k, smoothstep-weighted bilinear, U(−1, 1) lattice values from
//!   `seeded(seed)`, octave 0 first, row-major); a flat "wall" of 200 on x ∈ [360, 560),
//!   y ∈ [380, 440), a "shadow" of −20 on x ∈ [60, 300), y ∈ [330, 440) (0 after clipping).
//! - **Walkers**: silhouette ellipse (u/13)² + ((v−8)/30)² ≤ 1 ∪ disc u² + (v+31)² ≤ 7²
//!   (26 × 76 px, area π·(13·30 + 49) ≈ 1379 px); appearance μ + 25·n_k(u, v), n_k a
//!   two-octave value noise in the walker's own coordinates (spacing 6 and 3 px, lattice values
//!   from `stream(seed, [1, k])`) that moves rigidly with it; 4 × 4 supersampled coverage,
//!   pixel = cov·appearance + (1 − cov)·underlying; drawn in order A, B, C, D (later in front).
//! - **Noise**: N(0, 2²) per pixel and frame from `stream(seed, [2, t])`, rounded and clamped
//!   to 0..255. Each frame is generated on its own ([`WalkersScenario::frame`]), so a video
//!   never has to be held in memory and frame `t` does not depend on frames before it.
//!
//! **Pixel convention**: pixel `(x, y)` is the square [x, x+1) × [y, y+1) of the continuous
//! image plane [0, 800) × [0, 450) in which the walkers' centres move; its 16 coverage samples
//! are at (x + i/4, y + j/4), i, j ∈ 0..4. In-view fractions and visibilities are counted on
//! the same sample lattice (over the silhouette's whole box, outside the image too). This
//! convention reproduces every event of the spec's table (the ties at exactly half in view —
//! C at t = 68 and t = 388 — fall as the table says).
//!
//! **Ground truth** per frame and walker with a sample inside the image: the full silhouette
//! box [c.x − 13, c.x + 13) × [c.y − 38, c.y + 38) (unclipped), the in-view fraction, the
//! visibility (samples inside the image and not covered by a walker drawn later, over all),
//! and flag = in-view ≥ 0.5 (occluded walkers keep flag 1). MOT files are 1-based:
//! `frame = t + 1`, `left = c.x − 13 + 1`, `top = c.y − 38 + 1`.
//!
//! ```
//! use quarry_sim::walkers::{WalkersScenario, WalkersVariant};
//! let sc = WalkersScenario::new(WalkersVariant::V1)?;
//! assert_eq!((sc.width(), sc.height(), sc.len()), (800, 450, 450));
//! let f = sc.frame(100)?;
//! assert_eq!(f.data.len(), 800 * 450);
//! // at t = 100 walker A (id 1) is at x = -20 + 1.5 * 80 = 100, fully in view
//! let gt = sc.ground_truth(100)?;
//! let a = gt.iter().find(|g| g.id == 1).unwrap();
//! assert_eq!((a.full_box.cx, a.in_view, a.flag), (100.0, 1.0, true));
//! let ev = sc.events()?;
//! assert_eq!(ev.walkers[0].half_in_view, Some(34));
//! # Ok::<(), quarry_sim::SimError>(())
//! ```

use std::io::Write;

use quarry_core::rng::{seeded, stream};
use quarry_core::{BBox, CoreError, Plane};
use rand::Rng;
use rand_distr::{Distribution, Normal};
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

use crate::SimError;

/// Frame width of `walkers-v1`, pixels.
pub const WIDTH: u32 = 800;
/// Frame height of `walkers-v1`, pixels.
pub const HEIGHT: u32 = 450;
/// The seed of `walkers-v1` (background, textures and noise streams).
pub const SEED: u64 = 1;
/// Sub-samples per pixel side (4 × 4 supersampling).
const SUB: u32 = 4;
/// Largest frame side a custom scenario may ask for.
const MAX_SIDE: u32 = 8192;
/// Most frames a custom scenario may ask for.
const MAX_FRAMES: u64 = 1_000_000;

/// The three videos of spec 004 §5.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum WalkersVariant {
    /// `walkers-v1`: walkers A-D, 450 frames.
    V1,
    /// `walkers-v1-ab`: only A and B (the paper's two-target case), 450 frames.
    Ab,
    /// `walkers-v1-empty`: the background and noise without walkers, 200 frames.
    Empty,
}

impl WalkersVariant {
    /// All three, in the order above.
    pub const ALL: [WalkersVariant; 3] = [Self::V1, Self::Ab, Self::Empty];

    /// The sequence name: `walkers-v1`, `walkers-v1-ab` or `walkers-v1-empty`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::V1 => "walkers-v1",
            Self::Ab => "walkers-v1-ab",
            Self::Empty => "walkers-v1-empty",
        }
    }

    /// Parses `v1`, `ab`, `empty` or the full sequence names.
    ///
    /// Errors: anything else, naming the accepted values.
    pub fn parse(s: &str) -> Result<Self, SimError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "v1" | "walkers-v1" => Ok(Self::V1),
            "ab" | "walkers-v1-ab" => Ok(Self::Ab),
            "empty" | "walkers-v1-empty" => Ok(Self::Empty),
            _ => Err(CoreError::invalid(
                "walkers variant",
                format!("unknown variant {s:?}; expected v1, ab or empty"),
            )
            .into()),
        }
    }

    /// Number of frames.
    #[must_use]
    pub fn frames(self) -> u64 {
        match self {
            Self::V1 | Self::Ab => 450,
            Self::Empty => 200,
        }
    }

    /// The walkers of the variant (spec §5.2's path table).
    #[must_use]
    pub fn walkers(self) -> Vec<WalkerSpec> {
        let all = WalkerSpec::v1();
        match self {
            Self::V1 => all.to_vec(),
            Self::Ab => all[..2].to_vec(),
            Self::Empty => Vec::new(),
        }
    }
}

/// The shape of a walker.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum Silhouette {
    /// The spec's person: body ellipse (u/13)² + ((v−8)/30)² ≤ 1 ∪ head disc u² + (v+31)² ≤ 7².
    Person,
    /// Two ellipses of semi-axes `rx` × `ry`, one above the other, whose centres sit at
    /// v = ∓(`rest` + s(t))/2: `rest` apart at rest (overlapping when `rest` < 2·`ry`), and
    /// the extra separation s(t) rises linearly from 0 at `split_from` to `max_gap` half-way
    /// through `split_frames` and falls back to 0 at `split_from + split_frames` (spec §7.1 T3,
    /// the paper's "regions split and merge again").
    TwoLobes {
        /// Horizontal semi-axis of each lobe, pixels.
        rx: f64,
        /// Vertical semi-axis of each lobe, pixels.
        ry: f64,
        /// Distance between the lobes' centres at rest, pixels.
        rest: f64,
        /// First frame of the split.
        split_from: u64,
        /// Length of the split and rejoin, frames.
        split_frames: u64,
        /// Largest extra separation of the lobes, pixels.
        max_gap: f64,
    },
}

impl Silhouette {
    /// The extra lobe separation s(t) (0 for a person).
    #[must_use]
    pub fn gap(&self, t: u64) -> f64 {
        match *self {
            Self::Person => 0.0,
            Self::TwoLobes {
                split_from,
                split_frames,
                max_gap,
                ..
            } => {
                if t <= split_from || split_frames == 0 || t >= split_from + split_frames {
                    return 0.0;
                }
                let x = (t - split_from) as f64 / split_frames as f64; // (0, 1)
                max_gap * (1.0 - (2.0 * x - 1.0).abs())
            }
        }
    }

    /// Half-width and half-heights (up, down) of the silhouette's box at frame `t`.
    fn extent(&self, t: u64) -> (f64, f64, f64) {
        match *self {
            Self::Person => (13.0, 38.0, 38.0),
            Self::TwoLobes { rx, ry, rest, .. } => {
                let h = f64::midpoint(rest, self.gap(t)) + ry;
                (rx, h, h)
            }
        }
    }

    /// Is the local point (u, v) inside the silhouette at frame `t` (`gap` = s(t))?
    fn contains(&self, u: f64, v: f64, gap: f64) -> bool {
        match *self {
            Self::Person => {
                (u / 13.0).powi(2) + ((v - 8.0) / 30.0).powi(2) <= 1.0
                    || u * u + (v + 31.0) * (v + 31.0) <= 49.0
            }
            Self::TwoLobes { rx, ry, rest, .. } => {
                let d = f64::midpoint(rest, gap);
                let e = |vc: f64| (u / rx).powi(2) + ((v - vc) / ry).powi(2) <= 1.0;
                e(-d) || e(d)
            }
        }
    }

    /// The silhouette's area in square pixels (analytic).
    #[must_use]
    pub fn area(&self, t: u64) -> f64 {
        use std::f64::consts::PI;
        match *self {
            Self::Person => PI * (13.0 * 30.0 + 49.0),
            Self::TwoLobes { rx, ry, rest, .. } => {
                // two ellipses minus their lens (the lens of two unit circles at distance 2d)
                let d = f64::midpoint(rest, self.gap(t)) / ry; // half the centre distance, unit
                let lens = if d >= 1.0 {
                    0.0
                } else {
                    2.0 * (d.acos() - d * (1.0 - d * d).sqrt())
                };
                rx * ry * (2.0 * PI - lens)
            }
        }
    }

    /// Vertical offset of the silhouette's centroid below its centre, pixels.
    #[must_use]
    pub fn centroid_offset(&self) -> f64 {
        match self {
            // (1225.2 px² at v = 8, 153.9 px² at v = -31)
            Self::Person => (13.0 * 30.0 * 8.0 - 49.0 * 31.0) / (13.0 * 30.0 + 49.0),
            Self::TwoLobes { .. } => 0.0,
        }
    }
}

/// One walker: its name, identity, path and appearance.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct WalkerSpec {
    /// Ground-truth id (1-based; A = 1 ... D = 4 in `walkers-v1`).
    pub id: u32,
    /// Short name (`'A'` ...).
    pub name: char,
    /// First frame t₀ at which the walker exists.
    pub t0: u64,
    /// Centre at t₀, pixels.
    pub start: [f64; 2],
    /// Velocity, pixels per frame.
    pub velocity: [f64; 2],
    /// Mean grey μ of the appearance.
    pub mean: f64,
    /// Texture amplitude (25 in `walkers-v1`).
    pub texture: f64,
    /// The shape.
    pub silhouette: Silhouette,
}

impl WalkerSpec {
    /// A, B, C, D of spec §5.2.
    #[must_use]
    pub fn v1() -> [WalkerSpec; 4] {
        let w = |id, name, t0, start, velocity, mean| WalkerSpec {
            id,
            name,
            t0,
            start,
            velocity,
            mean,
            texture: 25.0,
            silhouette: Silhouette::Person,
        };
        [
            w(1, 'A', 20, [-20.0, 230.0], [1.5, 0.0], 85.0),
            w(2, 'B', 50, [820.0, 240.0], [-1.5, 0.0], 100.0),
            w(3, 'C', 60, [-20.0, 110.0], [2.5, 0.0], 75.0),
            w(4, 'D', 150, [680.0, 490.0], [0.0, -1.5], 110.0),
        ]
    }

    /// The centre at frame `t`, `None` before t₀.
    #[must_use]
    pub fn centre(&self, t: u64) -> Option<[f64; 2]> {
        (t >= self.t0).then(|| {
            let d = (t - self.t0) as f64;
            [
                self.start[0] + self.velocity[0] * d,
                self.start[1] + self.velocity[1] * d,
            ]
        })
    }

    /// The silhouette's centroid at frame `t` (the centre moved down by
    /// [`Silhouette::centroid_offset`]), `None` before t₀.
    #[must_use]
    pub fn centroid(&self, t: u64) -> Option<[f64; 2]> {
        self.centre(t)
            .map(|c| [c[0], c[1] + self.silhouette.centroid_offset()])
    }

    /// The full (unclipped) silhouette box at frame `t`, 0-based continuous coordinates.
    #[must_use]
    pub fn full_box(&self, t: u64) -> Option<BBox> {
        let c = self.centre(t)?;
        let (hw, up, down) = self.silhouette.extent(t);
        Some(BBox {
            cx: c[0],
            cy: c[1] + (down - up) / 2.0,
            w: 2.0 * hw,
            h: up + down,
        })
    }

    fn check(&self) -> Result<(), SimError> {
        let finite = self
            .start
            .iter()
            .chain(&self.velocity)
            .all(|v| v.is_finite())
            && self.mean.is_finite()
            && self.texture.is_finite();
        if !finite {
            return Err(CoreError::NonFinite {
                what: "walker start, velocity, mean or texture",
            }
            .into());
        }
        let bounded = self.start.iter().all(|v| v.abs() <= 1e6)
            && self.velocity.iter().all(|v| v.abs() <= 1e3)
            && self.mean.abs() <= 1e4
            && self.texture.abs() <= 1e4;
        if !bounded {
            return Err(CoreError::invalid(
                "walker",
                format!(
                    "{}: start must be within ±1e6 px, velocity within ±1e3 px/frame, mean and texture within ±1e4",
                    self.name
                ),
            )
            .into());
        }
        if let Silhouette::TwoLobes {
            rx,
            ry,
            rest,
            max_gap,
            ..
        } = self.silhouette
            && !(rx > 0.0
                && ry > 0.0
                && rx <= 1000.0
                && ry <= 1000.0
                && (0.0..=1000.0).contains(&rest)
                && (0.0..=1000.0).contains(&max_gap))
        {
            return Err(CoreError::invalid(
                "two-lobe silhouette",
                format!(
                    "rx {rx}, ry {ry} must be in (0, 1000], rest {rest} and max_gap {max_gap} in [0, 1000]"
                ),
            )
            .into());
        }
        Ok(())
    }
}

/// One ground-truth object of one frame (spec §5.2, written MOT16/17 style as §5.4 says).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct GroundTruthObject {
    /// Frame, 0-based (MOT files add 1).
    pub frame: u64,
    /// Walker id.
    pub id: u32,
    /// Full silhouette box (unclipped), 0-based continuous coordinates.
    pub full_box: BBox,
    /// Fraction of the silhouette inside the image.
    pub in_view: f64,
    /// Fraction of the silhouette inside the image and not covered by a walker in front.
    pub visibility: f64,
    /// Scored (in-view ≥ 0.5); unscored rows are written with flag 0.
    pub flag: bool,
}

impl GroundTruthObject {
    /// The MOT16/17 ground-truth line `frame,id,left,top,width,height,flag,1,visibility`
    /// (1-based frame and box).
    #[must_use]
    pub fn mot_line(&self) -> String {
        let [l, t, w, h] = self.full_box.to_ltwh();
        format!(
            "{},{},{},{},{},{},{},1,{:.4}",
            self.frame + 1,
            self.id,
            l + 1.0,
            t + 1.0,
            w,
            h,
            u8::from(self.flag),
            self.visibility
        )
    }
}

/// Events of one walker.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct WalkerEvents {
    /// Walker id.
    pub id: u32,
    /// Walker name.
    pub name: char,
    /// First frame with a sample in view (0-based).
    pub first_visible: Option<u64>,
    /// First frame with in-view ≥ 0.5 ("enters view", flag 1).
    pub half_in_view: Option<u64>,
    /// First frame after `half_in_view` with in-view < 0.5 ("starts leaving").
    pub below_half_from: Option<u64>,
    /// First frame after `first_visible` with no sample in view ("fully gone").
    pub gone_from: Option<u64>,
}

/// Two walkers whose silhouette boxes overlap in an interval of frames.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct OverlapEvent {
    /// The two walker ids (drawing order).
    pub ids: [u32; 2],
    /// The walker in front (drawn later).
    pub front: u32,
    /// First frame of the overlap.
    pub first: u64,
    /// Last frame of the overlap.
    pub last: u64,
    /// Smallest visibility of the walker behind during the interval.
    pub min_visibility_behind: f64,
}

/// A near pass: the smallest gap between two walkers' boxes that never overlap while both
/// are in view (C and D in `walkers-v1`), reported, not used for scoring.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct NearPass {
    /// The two walker ids.
    pub ids: [u32; 2],
    /// The frame of the smallest gap.
    pub frame: u64,
    /// The smallest gap between the boxes (Chebyshev: the larger of the x and y gaps), pixels.
    pub gap: f64,
}

/// The events of a scenario (`events.json`).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct WalkersEvents {
    /// Sequence name.
    pub sequence: String,
    /// Number of frames.
    pub frames: u64,
    /// Frame size.
    pub width: u32,
    /// Frame size.
    pub height: u32,
    /// Per walker, in drawing order.
    pub walkers: Vec<WalkerEvents>,
    /// Box overlaps (intervals of frames in which both walkers are in view).
    pub overlaps: Vec<OverlapEvent>,
    /// Near passes within 20 px without overlap.
    pub near_passes: Vec<NearPass>,
}

/// Value noise: octaves of smoothstep-weighted bilinear interpolation of U(−1, 1) lattice
/// values, summed with weights 2^−k and normalised by their sum.
#[derive(Debug, Clone)]
struct ValueNoise {
    octaves: Vec<Lattice>,
    norm: f64,
}

#[derive(Debug, Clone)]
struct Lattice {
    spacing: f64,
    origin: [f64; 2],
    nx: usize,
    ny: usize,
    values: Vec<f64>,
    weight: f64,
}

impl Lattice {
    fn at(&self, x: f64, y: f64) -> f64 {
        let fx = ((x - self.origin[0]) / self.spacing).max(0.0);
        let fy = ((y - self.origin[1]) / self.spacing).max(0.0);
        let i = (fx.floor() as usize).min(self.nx - 2);
        let j = (fy.floor() as usize).min(self.ny - 2);
        let s = |t: f64| {
            let t = t.clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        };
        let (tx, ty) = (s(fx - i as f64), s(fy - j as f64));
        let g = |a: usize, b: usize| self.values[b * self.nx + a];
        let top = g(i, j) * (1.0 - tx) + g(i + 1, j) * tx;
        let bot = g(i, j + 1) * (1.0 - tx) + g(i + 1, j + 1) * tx;
        top * (1.0 - ty) + bot * ty
    }
}

impl ValueNoise {
    /// Octaves of the given spacings over the rectangle `origin` + [0, size].
    fn new(spacings: &[f64], origin: [f64; 2], size: [f64; 2], rng: &mut impl Rng) -> Self {
        let mut octaves = Vec::with_capacity(spacings.len());
        let mut norm = 0.0;
        for (k, &s) in spacings.iter().enumerate() {
            let nx = (size[0] / s).ceil() as usize + 2;
            let ny = (size[1] / s).ceil() as usize + 2;
            let values = (0..nx * ny).map(|_| rng.random_range(-1.0..1.0)).collect();
            let weight = 0.5f64.powi(k as i32);
            norm += weight;
            octaves.push(Lattice {
                spacing: s,
                origin,
                nx,
                ny,
                values,
                weight,
            });
        }
        Self { octaves, norm }
    }

    fn at(&self, x: f64, y: f64) -> f64 {
        self.octaves
            .iter()
            .map(|o| o.weight * o.at(x, y))
            .sum::<f64>()
            / self.norm
    }
}

/// A seeded walkers video: the static background, the walkers and their textures.
#[derive(Debug, Clone)]
pub struct WalkersScenario {
    name: String,
    width: u32,
    height: u32,
    frames: u64,
    seed: u64,
    noise_sigma: f64,
    background: Vec<f64>,
    walkers: Vec<WalkerSpec>,
    textures: Vec<ValueNoise>,
}

impl WalkersScenario {
    /// One of the three videos of spec §5.2 (seed [`SEED`]).
    ///
    /// Errors: none for the built-in variants (the `Result` is that of [`Self::custom`]).
    pub fn new(variant: WalkersVariant) -> Result<Self, SimError> {
        let mut s = Self::custom(variant.frames(), variant.walkers())?;
        variant.name().clone_into(&mut s.name);
        Ok(s)
    }

    /// The `walkers-v1` background, noise and frame size with other walkers and length (for
    /// the tracker's unit scenarios, spec §7.1 T2-T3). Walker textures come from
    /// `stream(SEED, [1, k])` for the k-th walker, as in `walkers-v1`.
    ///
    /// Errors: no frames or more than 10⁶, a non-finite walker, an invalid two-lobe shape.
    pub fn custom(frames: u64, walkers: Vec<WalkerSpec>) -> Result<Self, SimError> {
        Self::with_size(WIDTH, HEIGHT, frames, walkers, SEED)
    }

    /// A walkers video of any size and seed: the same construction as `walkers-v1` (the
    /// wall and shadow are placed at the same pixel coordinates, clipped to the frame).
    ///
    /// Errors: a side of 0 or above 8192, no frames or more than 10⁶, a non-finite walker,
    /// an invalid two-lobe shape.
    pub fn with_size(
        width: u32,
        height: u32,
        frames: u64,
        walkers: Vec<WalkerSpec>,
        seed: u64,
    ) -> Result<Self, SimError> {
        if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
            return Err(CoreError::invalid(
                "walkers frame size",
                format!("{width}x{height}: each side must be in 1..={MAX_SIDE}"),
            )
            .into());
        }
        if frames == 0 || frames > MAX_FRAMES {
            return Err(CoreError::invalid(
                "walkers frames",
                format!("{frames}: must be in 1..={MAX_FRAMES}"),
            )
            .into());
        }
        for w in &walkers {
            w.check()?;
        }
        let mut rng = seeded(seed);
        let (fw, fh) = (f64::from(width), f64::from(height));
        let bg_noise = ValueNoise::new(&[64.0, 32.0, 16.0, 8.0], [0.0, 0.0], [fw, fh], &mut rng);
        let mut background = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                let v = if (360..560).contains(&x) && (380..440).contains(&y) {
                    200.0
                } else if (60..300).contains(&x) && (330..440).contains(&y) {
                    -20.0
                } else {
                    160.0 + 30.0 * bg_noise.at(f64::from(x), f64::from(y))
                };
                background.push(v);
            }
        }
        let textures = (0..walkers.len())
            .map(|k| {
                let (hw, up, down) = walkers[k].silhouette.extent(0);
                let (hw, hh) = (hw + 40.0, up.max(down) + 40.0); // room for lobe gaps
                ValueNoise::new(
                    &[6.0, 3.0],
                    [-hw, -hh],
                    [2.0 * hw, 2.0 * hh],
                    &mut stream(seed, &[1, k as u64]),
                )
            })
            .collect();
        Ok(Self {
            name: "walkers-custom".into(),
            width,
            height,
            frames,
            seed,
            noise_sigma: 2.0,
            background,
            walkers,
            textures,
        })
    }

    /// The first `frames` frames of this video (the frames, ground truth and events of those
    /// frames are unchanged).
    ///
    /// Errors: `frames` is 0 or more than the video has.
    pub fn truncated(mut self, frames: u64) -> Result<Self, SimError> {
        if frames == 0 || frames > self.frames {
            return Err(CoreError::invalid(
                "walkers frames",
                format!("{frames}: {} has 1..={} frames", self.name, self.frames),
            )
            .into());
        }
        self.frames = frames;
        Ok(self)
    }

    /// The same video under another sequence name (for custom scenarios).
    #[must_use]
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// The sequence name (`walkers-v1`, ...; `walkers-custom` for custom scenarios).
    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Frame width, pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Frame height, pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Number of frames.
    #[must_use]
    pub fn len(&self) -> u64 {
        self.frames
    }

    /// Always false (a scenario has at least one frame).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.frames == 0
    }

    /// The walkers, in drawing order.
    #[must_use]
    pub fn walkers(&self) -> &[WalkerSpec] {
        &self.walkers
    }

    /// The static background before noise (f64; the shadow is −20 here).
    #[must_use]
    pub fn background(&self) -> Plane<f64> {
        Plane {
            width: self.width,
            height: self.height,
            data: self.background.clone(),
        }
    }

    fn check_frame(&self, t: u64) -> Result<(), SimError> {
        if t >= self.frames {
            return Err(CoreError::invalid(
                "walkers frame",
                format!("t = {t}, but {} has frames 0..{}", self.name, self.frames),
            )
            .into());
        }
        Ok(())
    }

    /// Frame `t` (0-based): the background, the walkers in drawing order, the noise.
    ///
    /// Errors: `t` beyond the last frame.
    pub fn frame(&self, t: u64) -> Result<Plane<u8>, SimError> {
        self.check_frame(t)?;
        let mut img = self.background.clone();
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let inv = 1.0 / f64::from(SUB);
        for (wk, tex) in self.walkers.iter().zip(&self.textures) {
            let Some(c) = wk.centre(t) else { continue };
            let gap = wk.silhouette.gap(t);
            let (hw, up, down) = wk.silhouette.extent(t);
            let x0 = ((c[0] - hw).floor() as i64 - 1).max(0);
            let x1 = ((c[0] + hw).ceil() as i64 + 1).min(w);
            let y0 = ((c[1] - up).floor() as i64 - 1).max(0);
            let y1 = ((c[1] + down).ceil() as i64 + 1).min(h);
            for y in y0..y1 {
                for x in x0..x1 {
                    let mut n = 0u32;
                    for j in 0..SUB {
                        for i in 0..SUB {
                            let u = x as f64 + f64::from(i) * inv - c[0];
                            let v = y as f64 + f64::from(j) * inv - c[1];
                            n += u32::from(wk.silhouette.contains(u, v, gap));
                        }
                    }
                    if n == 0 {
                        continue;
                    }
                    let cov = f64::from(n) / f64::from(SUB * SUB);
                    let (u, v) = (x as f64 + 0.5 - c[0], y as f64 + 0.5 - c[1]);
                    let app = wk.mean + wk.texture * tex.at(u, v);
                    let p = &mut img[(y * w + x) as usize];
                    *p = cov * app + (1.0 - cov) * *p;
                }
            }
        }
        let mut rng = stream(self.seed, &[2, t]);
        let normal = Normal::new(0.0, self.noise_sigma)
            .map_err(|e| SimError::Core(CoreError::invalid("noise sigma", e.to_string())))?;
        let data = img
            .iter()
            .map(|v| (v + normal.sample(&mut rng)).round().clamp(0.0, 255.0) as u8)
            .collect();
        Ok(Plane::from_vec(self.width, self.height, data)?)
    }

    /// Frames `0..len()` one at a time.
    pub fn frames(&self) -> impl Iterator<Item = Result<Plane<u8>, SimError>> + '_ {
        (0..self.frames).map(|t| self.frame(t))
    }

    /// The ground truth of frame `t`: one object per walker with a sample in view.
    ///
    /// Errors: `t` beyond the last frame.
    pub fn ground_truth(&self, t: u64) -> Result<Vec<GroundTruthObject>, SimError> {
        self.check_frame(t)?;
        let (fw, fh) = (f64::from(self.width), f64::from(self.height));
        let boxes: Vec<Option<BBox>> = self.walkers.iter().map(|w| w.full_box(t)).collect();
        let mut out = Vec::new();
        for (k, wk) in self.walkers.iter().enumerate() {
            let Some(b) = boxes[k] else { continue };
            let [l, tp, bw, bh] = b.to_ltwh();
            let inside = l >= 0.0 && tp >= 0.0 && l + bw <= fw && tp + bh <= fh;
            if l + bw <= 0.0 || tp + bh <= 0.0 || l >= fw || tp >= fh {
                continue;
            }
            let front: Vec<usize> = (k + 1..self.walkers.len())
                .filter(|&j| boxes[j].is_some_and(|o| overlap(&b, &o)))
                .collect();
            let (in_view, visibility) = if inside && front.is_empty() {
                (1.0, 1.0)
            } else {
                self.count(t, k, &front)
            };
            if in_view == 0.0 {
                continue;
            }
            out.push(GroundTruthObject {
                frame: t,
                id: wk.id,
                full_box: b,
                in_view,
                visibility,
                flag: in_view >= 0.5,
            });
        }
        Ok(out)
    }

    /// In-view fraction and visibility of walker `k` at `t` on the sample lattice.
    fn count(&self, t: u64, k: usize, front: &[usize]) -> (f64, f64) {
        let wk = &self.walkers[k];
        let Some(c) = wk.centre(t) else {
            return (0.0, 0.0);
        };
        let gap = wk.silhouette.gap(t);
        let (hw, up, down) = wk.silhouette.extent(t);
        let (fw, fh) = (f64::from(self.width), f64::from(self.height));
        let others: Vec<([f64; 2], f64, &Silhouette)> = front
            .iter()
            .filter_map(|&j| {
                let o = &self.walkers[j];
                Some((o.centre(t)?, o.silhouette.gap(t), &o.silhouette))
            })
            .collect();
        let inv = 1.0 / f64::from(SUB);
        let (mut total, mut in_view, mut visible) = (0u64, 0u64, 0u64);
        for y in ((c[1] - up).floor() as i64 - 1)..=((c[1] + down).ceil() as i64 + 1) {
            for x in ((c[0] - hw).floor() as i64 - 1)..=((c[0] + hw).ceil() as i64 + 1) {
                for j in 0..SUB {
                    for i in 0..SUB {
                        let sx = x as f64 + f64::from(i) * inv;
                        let sy = y as f64 + f64::from(j) * inv;
                        if !wk.silhouette.contains(sx - c[0], sy - c[1], gap) {
                            continue;
                        }
                        total += 1;
                        if !(0.0..fw).contains(&sx) || !(0.0..fh).contains(&sy) {
                            continue;
                        }
                        in_view += 1;
                        if !others
                            .iter()
                            .any(|(oc, og, s)| s.contains(sx - oc[0], sy - oc[1], *og))
                        {
                            visible += 1;
                        }
                    }
                }
            }
        }
        if total == 0 {
            return (0.0, 0.0);
        }
        (in_view as f64 / total as f64, visible as f64 / total as f64)
    }

    /// The ground truth of every frame, in frame order.
    ///
    /// Errors: none in practice (the frames are in range).
    pub fn ground_truth_all(&self) -> Result<Vec<GroundTruthObject>, SimError> {
        let mut out = Vec::new();
        for t in 0..self.frames {
            out.extend(self.ground_truth(t)?);
        }
        Ok(out)
    }

    /// Writes the ground truth of every frame as MOT16/17 `gt.txt` lines (spec §5.4).
    ///
    /// Errors: the writer fails.
    pub fn write_ground_truth<W: Write>(&self, mut w: W) -> Result<(), SimError> {
        let io = |e: std::io::Error| SimError::Io {
            path: "<gt writer>".into(),
            reason: e.to_string(),
        };
        for t in 0..self.frames {
            for g in self.ground_truth(t)? {
                writeln!(w, "{}", g.mot_line()).map_err(io)?;
            }
        }
        w.flush().map_err(io)
    }

    /// The scenario's events: entries, exits, box overlaps and near passes (`events.json`).
    ///
    /// Errors: none in practice (the frames are in range).
    pub fn events(&self) -> Result<WalkersEvents, SimError> {
        let n = self.walkers.len();
        let mut ev: Vec<WalkerEvents> = self
            .walkers
            .iter()
            .map(|w| WalkerEvents {
                id: w.id,
                name: w.name,
                first_visible: None,
                half_in_view: None,
                below_half_from: None,
                gone_from: None,
            })
            .collect();
        let mut open: Vec<Option<OverlapEvent>> = vec![None; n * n];
        let mut overlaps = Vec::new();
        let mut near: Vec<Option<NearPass>> = vec![None; n * n];
        let mut ever_overlap = vec![false; n * n];
        for t in 0..self.frames {
            let gt = self.ground_truth(t)?;
            let of = |id: u32| gt.iter().find(|g| g.id == id);
            for e in &mut ev {
                let g = of(e.id);
                match g {
                    Some(g) => {
                        e.first_visible.get_or_insert(t);
                        if g.flag {
                            e.half_in_view.get_or_insert(t);
                        } else if e.half_in_view.is_some() && e.below_half_from.is_none() {
                            e.below_half_from = Some(t);
                        }
                    }
                    None => {
                        if e.first_visible.is_some() && e.gone_from.is_none() {
                            e.gone_from = Some(t);
                        }
                    }
                }
            }
            for a in 0..n {
                for b in a + 1..n {
                    let (ia, ib) = (self.walkers[a].id, self.walkers[b].id);
                    let pair = (of(ia), of(ib));
                    let slot = a * n + b;
                    let now = match pair {
                        (Some(ga), Some(gb)) if overlap(&ga.full_box, &gb.full_box) => {
                            Some(ga.visibility)
                        }
                        _ => None,
                    };
                    match (now, open[slot].as_mut()) {
                        (Some(vis), Some(o)) => {
                            o.last = t;
                            o.min_visibility_behind = o.min_visibility_behind.min(vis);
                        }
                        (Some(vis), None) => {
                            ever_overlap[slot] = true;
                            open[slot] = Some(OverlapEvent {
                                ids: [ia, ib],
                                front: ib,
                                first: t,
                                last: t,
                                min_visibility_behind: vis,
                            });
                        }
                        (None, Some(_)) => overlaps.extend(open[slot].take()),
                        (None, None) => {}
                    }
                    if let (Some(ga), Some(gb)) = pair
                        && now.is_none()
                    {
                        let g = box_gap(&ga.full_box, &gb.full_box);
                        if g <= 20.0 && near[slot].as_ref().is_none_or(|p| g < p.gap) {
                            near[slot] = Some(NearPass {
                                ids: [ia, ib],
                                frame: t,
                                gap: g,
                            });
                        }
                    }
                }
            }
        }
        overlaps.extend(open.into_iter().flatten());
        overlaps.sort_by_key(|o| (o.first, o.ids));
        let near_passes = near
            .into_iter()
            .enumerate()
            .filter(|(k, _)| !ever_overlap[*k])
            .filter_map(|(_, p)| p)
            .collect();
        Ok(WalkersEvents {
            sequence: self.name.clone(),
            frames: self.frames,
            width: self.width,
            height: self.height,
            walkers: ev,
            overlaps,
            near_passes,
        })
    }

    /// The frame rate written to `seqinfo.ini` (25 fps, a nominal value: the scenario is
    /// defined in frames).
    #[must_use]
    pub fn frame_rate(&self) -> u32 {
        25
    }

    /// The MOTChallenge `seqinfo.ini` of this video (image files `img1/NNNNNN.png`).
    #[must_use]
    pub fn seqinfo(&self) -> String {
        format!(
            "[Sequence]\nname={}\nimDir=img1\nframeRate={}\nseqLength={}\nimWidth={}\nimHeight={}\nimExt=.png\n",
            self.name,
            self.frame_rate(),
            self.frames,
            self.width,
            self.height
        )
    }
}

/// Do two boxes overlap (positive-area intersection)?
fn overlap(a: &BBox, b: &BBox) -> bool {
    (a.cx - b.cx).abs() < f64::midpoint(a.w, b.w) && (a.cy - b.cy).abs() < f64::midpoint(a.h, b.h)
}

/// The Chebyshev gap between two boxes (0 when they touch or overlap).
fn box_gap(a: &BBox, b: &BBox) -> f64 {
    let gx = (a.cx - b.cx).abs() - f64::midpoint(a.w, b.w);
    let gy = (a.cy - b.cy).abs() - f64::midpoint(a.h, b.h);
    gx.max(gy).max(0.0)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn events_match_the_spec_table() {
        let sc = WalkersScenario::new(WalkersVariant::V1).unwrap();
        let ev = sc.events().unwrap();
        let by = |n: char| ev.walkers.iter().find(|w| w.name == n).unwrap().clone();
        assert_eq!(by('A').half_in_view, Some(34));
        assert_eq!(by('B').half_in_view, Some(64));
        assert_eq!(by('C').half_in_view, Some(68));
        assert_eq!(by('C').below_half_from, Some(388));
        assert_eq!(by('C').gone_from, Some(394));
        assert_eq!(by('D').half_in_view, Some(181));
        assert_eq!(by('A').gone_from, None);
        let ab = ev.overlaps.iter().find(|o| o.ids == [1, 2]).unwrap();
        assert_eq!((ab.first, ab.last, ab.front), (307, 323, 2));
        assert!(ab.min_visibility_behind < 0.3, "{ab:?}");
        // C and D pass without their boxes overlapping, within a few pixels (spec: ≈ 4 px)
        assert!(ev.overlaps.iter().all(|o| o.ids != [3, 4]));
        let cd = ev.near_passes.iter().find(|p| p.ids == [3, 4]).unwrap();
        assert!(cd.gap < 8.0 && (330..=360).contains(&cd.frame), "{cd:?}");
        assert_eq!(ev.overlaps.len(), 1, "{:?}", ev.overlaps);
    }

    #[test]
    fn ground_truth_of_a_crossing() {
        let sc = WalkersScenario::new(WalkersVariant::V1).unwrap();
        let gt = sc.ground_truth(315).unwrap();
        let a = gt.iter().find(|g| g.id == 1).unwrap();
        let b = gt.iter().find(|g| g.id == 2).unwrap();
        assert_eq!((a.full_box.cx, b.full_box.cx), (422.5, 422.5));
        assert!(a.flag && a.in_view == 1.0 && a.visibility < 0.3, "{a:?}");
        assert_eq!(b.visibility, 1.0);
        assert_eq!(
            a.mot_line(),
            format!("316,1,410.5,193,26,76,1,1,{:.4}", a.visibility)
        );
        // before t0 and after leaving: no row
        assert!(sc.ground_truth(10).unwrap().is_empty());
        assert!(sc.ground_truth(400).unwrap().iter().all(|g| g.id != 3));
        assert!(sc.ground_truth(450).is_err());
        assert!(sc.frame(450).is_err());
    }

    #[test]
    fn silhouette_area_and_coverage() {
        let s = Silhouette::Person;
        let area = s.area(0);
        assert!((area - 1364.0).abs() / 1364.0 < 0.02, "{area}");
        // the coverage of a walker fully in view sums to the area within 0.5 %
        let mut wk = WalkerSpec::v1()[0];
        wk.start = [100.3, 100.7];
        wk.t0 = 0;
        wk.texture = 0.0;
        wk.mean = 0.0;
        let mut sc = WalkersScenario::with_size(200, 200, 1, vec![wk], 3).unwrap();
        sc.noise_sigma = 1e-9;
        sc.background.iter_mut().for_each(|v| *v = 255.0);
        let f = sc.frame(0).unwrap();
        let cov: f64 = f.data.iter().map(|&v| (255.0 - f64::from(v)) / 255.0).sum();
        assert!((cov - area).abs() / area < 0.005, "{cov} vs {area}");
        // and the lattice count agrees
        let n = sc.count(0, 0, &[]);
        assert_eq!(n, (1.0, 1.0));
    }

    #[test]
    fn empty_and_ab() {
        let e = WalkersScenario::new(WalkersVariant::Empty).unwrap();
        assert_eq!(e.len(), 200);
        assert!(e.ground_truth_all().unwrap().is_empty());
        let ab = WalkersScenario::new(WalkersVariant::Ab).unwrap();
        let ids: std::collections::BTreeSet<u32> = ab
            .ground_truth_all()
            .unwrap()
            .iter()
            .map(|g| g.id)
            .collect();
        assert_eq!(ids.into_iter().collect::<Vec<_>>(), vec![1, 2]);
        // the same background under the walkers: frame 0 (nobody in view) equals v1's
        let v1 = WalkersScenario::new(WalkersVariant::V1).unwrap();
        assert_eq!(v1.frame(0).unwrap(), e.frame(0).unwrap());
        assert_eq!(WalkersVariant::parse("AB").unwrap(), WalkersVariant::Ab);
        assert!(WalkersVariant::parse("walkers-v2").is_err());
        let short = ab.clone().truncated(10).unwrap();
        assert_eq!(short.len(), 10);
        assert_eq!(short.frame(9).unwrap(), ab.frame(9).unwrap());
        assert!(short.frame(10).is_err());
        assert!(ab.clone().truncated(0).is_err() && ab.truncated(451).is_err());
    }

    #[test]
    fn background_statistics() {
        let sc = WalkersScenario::new(WalkersVariant::Empty).unwrap();
        let f = sc.frame(0).unwrap();
        let px = |x: u32, y: u32| f.data[(y * 800 + x) as usize];
        // the shadow is exactly 0, the wall is 200 ± noise
        assert!((60..300).all(|x| px(x, 400) == 0));
        assert!((360..560).all(|x| px(x, 400).abs_diff(200) <= 10));
        let bg = sc.background();
        let open: Vec<f64> = bg.data[..800 * 300].to_vec();
        let mean = open.iter().sum::<f64>() / open.len() as f64;
        assert!((mean - 160.0).abs() < 8.0, "{mean}");
        assert!(open.iter().all(|v| (130.0..=190.0).contains(v)));
    }

    #[test]
    fn two_lobes_split_and_rejoin() {
        let s = Silhouette::TwoLobes {
            rx: 10.0,
            ry: 15.0,
            rest: 27.0,
            split_from: 10,
            split_frames: 20,
            max_gap: 12.0,
        };
        assert_eq!(s.gap(10), 0.0);
        assert_eq!(s.gap(20), 12.0);
        assert_eq!(s.gap(30), 0.0);
        // overlapping at rest (one blob), apart at the peak
        assert!(s.contains(0.0, 0.0, s.gap(0)));
        assert!(!s.contains(0.0, 0.0, s.gap(20)));
        assert!(s.area(0) < s.area(20));
    }

    #[test]
    fn bad_custom_scenarios_are_errors() {
        let mut w = WalkerSpec::v1()[0];
        assert!(WalkersScenario::custom(0, vec![w]).is_err());
        w.velocity[0] = f64::NAN;
        assert!(WalkersScenario::custom(10, vec![w]).is_err());
        assert!(WalkersScenario::with_size(0, 10, 10, vec![], 1).is_err());
        let mut far = WalkerSpec::v1()[0];
        far.start = [1e300, 0.0];
        assert!(WalkersScenario::custom(10, vec![far]).is_err());
        far.start = [0.0, 0.0];
        far.velocity = [1e9, 0.0];
        assert!(WalkersScenario::custom(10, vec![far]).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6))]
        /// Any frame is bit-identical when generated twice, alone or after others.
        #[test]
        fn frames_are_deterministic(t in 0u64..450) {
            let a = WalkersScenario::new(WalkersVariant::V1).unwrap();
            let b = WalkersScenario::new(WalkersVariant::V1).unwrap();
            let _ = b.frame(t.saturating_sub(1)).unwrap();
            prop_assert_eq!(a.frame(t).unwrap(), b.frame(t).unwrap());
            prop_assert_eq!(a.ground_truth(t).unwrap(), b.ground_truth(t).unwrap());
        }

        /// Every ground-truth row has in-view and visibility in [0, 1], visibility ≤ in-view,
        /// and the 26 × 76 box.
        #[test]
        fn ground_truth_is_consistent(t in 0u64..450) {
            let sc = WalkersScenario::new(WalkersVariant::V1).unwrap();
            for g in sc.ground_truth(t).unwrap() {
                prop_assert!(g.in_view > 0.0 && g.in_view <= 1.0);
                prop_assert!(g.visibility >= 0.0 && g.visibility <= g.in_view);
                prop_assert_eq!((g.full_box.w, g.full_box.h), (26.0, 76.0));
                prop_assert_eq!(g.flag, g.in_view >= 0.5);
            }
        }
    }
}
