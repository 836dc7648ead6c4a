//! The motion front end of spec 004 (§2.2-2.8): per frame, segment (ramp, f64 blur, minima,
//! watershed), map the regions onto the previous frame's, extend the minimum trajectories and
//! run the moving-point test. The `quarry motion` command and [`WatershedSiftTracker`]
//! (crate::watershed_sift::WatershedSiftTracker) both run this loop.

use super::config::Polarity;
use crate::TrackerError;
use quarry_core::{Plane, Segmentation};
use quarry_vision::{
    MinimumTrajectories, MotionStats, MotionTest, RampBlurWatershed, RegionMapping,
};

/// Segmentation, mapping and moving points, frame after frame.
#[derive(Debug, Clone)]
pub struct MotionFrontEnd {
    segmenter: RampBlurWatershed,
    polarity: Polarity,
    test: MotionTest,
    previous: Option<Segmentation>,
    current: Option<Segmentation>,
    mapping: Option<RegionMapping>,
    trajectories: Option<MinimumTrajectories>,
    moving: Vec<(u32, MotionStats)>,
}

impl MotionFrontEnd {
    /// A front end with blur `sigma`, `levels` grey levels (256 for 8-bit), the person
    /// `polarity` and the moving-point `test`.
    ///
    /// Errors: an invalid σ or test.
    pub fn new(
        sigma: f64,
        levels: u32,
        polarity: Polarity,
        test: MotionTest,
    ) -> Result<Self, TrackerError> {
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(TrackerError::config(
                "watershed_sift",
                format!("sigma must be finite and > 0, got {sigma}"),
            ));
        }
        test.validate()?;
        Ok(Self {
            segmenter: RampBlurWatershed {
                sigma,
                levels,
                ..RampBlurWatershed::default()
            },
            polarity,
            test,
            previous: None,
            current: None,
            mapping: None,
            trajectories: None,
            moving: Vec::new(),
        })
    }

    /// Processes one grey frame: after it, [`current`](Self::current) is its segmentation,
    /// [`mapping`](Self::mapping) the mapping from the previous frame (none on the first
    /// frame), and [`moving`](Self::moving) its moving points.
    ///
    /// Errors: a frame smaller than 2×2, pixels at or above `levels`, or a frame of another
    /// size than the previous one.
    pub fn step(&mut self, frame: &Plane<u8>) -> Result<(), TrackerError> {
        if let Some(c) = &self.current
            && c.labels.dimensions() != frame.dimensions()
        {
            return Err(TrackerError::State(format!(
                "frame of {}x{} after frames of {}x{}: every frame of a sequence must have the same size",
                frame.width, frame.height, c.labels.width, c.labels.height
            )));
        }
        let seg = self.segment(frame)?;
        if let (Some(prev), Some(tr)) = (&self.current, &mut self.trajectories) {
            let map = RegionMapping::new(prev, &seg)?;
            tr.advance(&map, &seg)?;
            self.mapping = Some(map);
        } else {
            self.trajectories = Some(MinimumTrajectories::new(self.test.n, &seg)?);
            self.mapping = None;
        }
        self.moving = match &self.trajectories {
            Some(tr) => tr.moving_points(&self.test)?,
            None => Vec::new(),
        };
        self.previous = self.current.replace(seg);
        Ok(())
    }

    /// The segmentation stage alone: ramp, blur, minima and watershed of `frame` in the
    /// front end's polarity, without touching the front end's state (what [`step`](Self::step)
    /// runs first; the per-stage bench times it on its own).
    ///
    /// Errors: a frame smaller than 2×2 or pixels at or above `levels`.
    pub fn segment(&self, frame: &Plane<u8>) -> Result<Segmentation, TrackerError> {
        Ok(match self.polarity {
            Polarity::Dark => self.segmenter.run(frame)?.segmentation,
            Polarity::Bright => {
                let top = (self.segmenter.levels.saturating_sub(1)).min(255) as u8;
                let inv = frame.map(|&v| top.saturating_sub(v));
                self.segmenter.run(&inv)?.segmentation
            }
        })
    }

    /// The last frame's segmentation.
    pub fn current(&self) -> Option<&Segmentation> {
        self.current.as_ref()
    }

    /// The segmentation of the frame before the last.
    pub fn previous(&self) -> Option<&Segmentation> {
        self.previous.as_ref()
    }

    /// The mapping from the frame before the last to the last one.
    pub fn mapping(&self) -> Option<&RegionMapping> {
        self.mapping.as_ref()
    }

    /// The trajectories of the last frame's minima.
    pub fn trajectories(&self) -> Option<&MinimumTrajectories> {
        self.trajectories.as_ref()
    }

    /// The last frame's moving points: `(label, stats)` in label order.
    pub fn moving(&self) -> &[(u32, MotionStats)] {
        &self.moving
    }

    /// The moving-point test.
    pub fn test(&self) -> &MotionTest {
        &self.test
    }
}
