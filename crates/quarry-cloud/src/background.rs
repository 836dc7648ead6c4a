//! The chi-square background model of spec 003 §2.2: per-beam statistical distance (3), χ²₂
//! static probability (4)–(5), the region constraint (6), and the long-term per-beam background
//! with the revealed-background rule.
//!
//! Per beam n the model keeps a ring buffer of the last `m` readings. For the current point
//! `p = (x, y)` and the mean `p̄` of the valid window entries (the current reading excluded),
//! `D² = (p − p̄)ᵀ S⁻¹ (p − p̄)` with `S = diag(σ², σ²)`, and `P = exp(−D²/2)` is the static
//! probability. A beam is a static *candidate* when `P > P_th = 0.9`; the region constraint then
//! keeps a candidate static only if its valid neighbours within `δ` in the same scan hold a
//! strict majority of candidates (an empty neighbourhood keeps it static). σ is a tolerance,
//! `σ = κ·σ_d(d)` with `κ = 7` (spec §6 A1).
//!
//! The long-term background `b_n` (preset `faithful`; off in `literal`) is the median of the
//! warm-up readings, follows static readings with rate `α_b`, is relearned after `T_relearn` of
//! continuous static labels away from it, and overrides: a valid reading within
//! `τ_g(d) = max(0.03, 3σ_d(d))` of `b_n` is static.
//!
//! Choices where the spec is silent (documented here and in the report): the override is
//! applied after the region vote (which uses the preliminary labels only); the relearn rule
//! also learns `b_n` for beams that had none after warm-up; a scan whose timestamp is earlier
//! than the previous one is rejected with an error and leaves the model unchanged.

use quarry_core::{BackgroundModel, BeamLabel, CoreError, Point2, PolarScan, ScanGeometry, TimeUs};

use crate::error::Result;
use crate::kd::KdIndex;
use crate::scan::{BeamTable, check_scan, sigma_d};

/// The χ²₂ density of eq. (4): `f(x) = ½ exp(−x/2)` for `x ≥ 0` (0 below).
#[inline]
pub fn chi2_2dof_pdf(x: f64) -> f64 {
    if x < 0.0 { 0.0 } else { 0.5 * (-x / 2.0).exp() }
}

/// The static probability of eq. (5): `P = 1 − ∫₀^{D²} f = exp(−D²/2)`. (Not `1 − exp(−D²/2)`,
/// which is the χ²₂ CDF, the *dynamic* probability; spec §6 A2.)
#[inline]
pub fn static_probability(d2: f64) -> f64 {
    (-d2 / 2.0).exp()
}

/// The statistical distance of eq. (3) in its matrix form: `Aᵀ S⁻¹ A` with `A = p − mean` and
/// `S = diag(σ_x², σ_y²)`.
#[inline]
pub fn statistical_distance2(p: &Point2, mean: &Point2, sigma_x: f64, sigma_y: f64) -> f64 {
    let a = p - mean;
    let s_inv = nalgebra::Matrix2::new(
        1.0 / (sigma_x * sigma_x),
        0.0,
        0.0,
        1.0 / (sigma_y * sigma_y),
    );
    (a.transpose() * s_inv * a)[(0, 0)]
}

/// The region constraint (6), one pass over preliminary labels: for each candidate `n`
/// (`candidate[n]`, which must have a point), count the candidates `n_s` and non-candidates `n_d`
/// among the *other* valid points within `delta`; it stays static iff `n_s > n_d` or the
/// neighbourhood is empty. Returns the final static flags (`false` for every non-candidate and
/// every invalid beam).
pub fn region_constraint(
    points: &[Option<Point2>],
    candidate: &[bool],
    delta: f64,
) -> Result<Vec<bool>> {
    quarry_core::ensure_len(candidate.len(), points.len(), "candidate flags")?;
    if !(delta.is_finite() && delta >= 0.0) {
        return Err(CoreError::invalid("delta", "must be finite and >= 0").into());
    }
    let beams: Vec<usize> = (0..points.len()).filter(|&n| points[n].is_some()).collect();
    let pts: Vec<Point2> = beams.iter().filter_map(|&n| points[n]).collect();
    let index = KdIndex::new(&pts)?;
    // candidate / non-candidate counts per distinct point (identical points share an id)
    let mut cand_u = vec![0usize; index.n_unique()];
    let mut non_u = vec![0usize; index.n_unique()];
    for (k, &n) in beams.iter().enumerate() {
        let u = index.unique_index(k).unwrap_or(0);
        if candidate[n] {
            cand_u[u] += 1;
        } else {
            non_u[u] += 1;
        }
    }
    let mut out = vec![false; points.len()];
    for (k, &n) in beams.iter().enumerate() {
        if !candidate[n] {
            continue;
        }
        let (mut ns, mut nd) = (0usize, 0usize);
        index.for_each_unique_id_within(&pts[k], delta, |u, _, _| {
            ns += cand_u[u];
            nd += non_u[u];
        });
        ns = ns.saturating_sub(1); // the candidate itself
        out[n] = (ns + nd == 0) || ns > nd;
    }
    Ok(out)
}

/// [`region_constraint`] for the points of one scan in the sensor frame, beam `n` at angle
/// `angle_min + n·angle_increment` (same result, without a kd-tree).
///
/// A point at range `r` from the sensor is farther than `r·sin|Δφ|` from any point whose beam
/// is `Δφ` away (`r` beyond 90°), so only the beams within `asin(δ/r)` of it (and, for fields of
/// view near 360°, those within that angle across the wrap) can be neighbours; points closer
/// than δ to the sensor are compared with every beam. Cost: about 2·δ/(r·Δφ) distance checks
/// per candidate instead of a kd-tree build and query.
pub fn region_constraint_scan(
    points: &[Option<Point2>],
    candidate: &[bool],
    delta: f64,
    angle_increment: f64,
) -> Result<Vec<bool>> {
    quarry_core::ensure_len(candidate.len(), points.len(), "candidate flags")?;
    if !(delta.is_finite() && delta >= 0.0) {
        return Err(CoreError::invalid("delta", "must be finite and >= 0").into());
    }
    let inc = angle_increment.abs();
    if !(inc.is_finite() && inc > 0.0) {
        return Err(CoreError::invalid("angle_increment", "must be finite and non-zero").into());
    }
    let n_beams = points.len();
    let d2max = delta * delta;
    // beams per full turn (wrap-around distance in beam indices)
    let per_turn = std::f64::consts::TAU / inc;
    // The vote is `ns > nd` (or an empty neighbourhood). The non-candidates (people, mixed
    // pixels) are few, so nd is counted first over them alone; then candidates are counted
    // outward from beam n only until ns > nd. Same result as counting everything.
    let non_cand: Vec<usize> = (0..n_beams)
        .filter(|&j| points[j].is_some() && !candidate[j])
        .collect();
    let mut out = vec![false; n_beams];
    for n in 0..n_beams {
        if !candidate[n] {
            continue;
        }
        let Some(p) = points[n] else { continue };
        let near = |j: usize| {
            points[j]
                .is_some_and(|q| (q.x - p.x) * (q.x - p.x) + (q.y - p.y) * (q.y - p.y) <= d2max)
        };
        let r = p.x.hypot(p.y);
        let w = if r > delta {
            // +1 beam against rounding of the angles
            ((delta / r).asin() / inc).floor() + 1.0
        } else {
            f64::INFINITY
        };
        // the index ranges (inclusive) that can hold neighbours: [lo, hi] around n, and the
        // ranges within w across the wrap
        let wrap_from = per_turn - w; // |n − j| ≥ this is within w across the wrap
        let (lo, hi, wrap) = if !w.is_finite() || 2.0 * w + 1.0 >= n_beams as f64 || wrap_from <= w
        {
            (0, n_beams - 1, [None, None])
        } else {
            let wi = w as usize;
            let mut wrap: [Option<(usize, usize)>; 2] = [None, None];
            if wrap_from < n_beams as f64 {
                let k = wrap_from.ceil() as usize;
                if n >= k {
                    wrap[0] = Some((0, n - k));
                }
                if n + k < n_beams {
                    wrap[1] = Some((n + k, n_beams - 1));
                }
            }
            (n.saturating_sub(wi), (n + wi).min(n_beams - 1), wrap)
        };
        let ranges = [Some((lo, hi)), wrap[0], wrap[1]];
        let mut nd = 0usize;
        for &(a, b) in ranges.iter().flatten() {
            let from = non_cand.partition_point(|&j| j < a);
            nd += non_cand[from..]
                .iter()
                .take_while(|&&j| j <= b)
                .filter(|&&j| near(j))
                .count();
        }
        if nd == 0 {
            out[n] = true; // ns > 0 or an empty neighbourhood: static either way
            continue;
        }
        let mut ns = 0usize;
        let mut count = |j: usize| {
            if j != n && candidate[j] && near(j) {
                ns += 1;
            }
            ns > nd
        };
        // outward from n within [lo, hi], then the wrap ranges
        let mut decided = false;
        for d in 1..=(n - lo).max(hi - n) {
            if (d <= n - lo && count(n - d)) || (n + d <= hi && count(n + d)) {
                decided = true;
                break;
            }
        }
        if !decided {
            'wrap: for &(a, b) in wrap.iter().flatten() {
                for j in a..=b {
                    if count(j) {
                        break 'wrap;
                    }
                }
            }
        }
        out[n] = ns > nd;
    }
    Ok(out)
}

/// The override's tolerance τ_g(d) = max(3σ_d(d), 0.03 m) (spec 003 §2.2): a reading within it
/// of `b_n` agrees with the long-term background.
fn tau_g(d: f64) -> f64 {
    (3.0 * sigma_d(d)).max(0.03)
}

/// How σ is chosen per beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SigmaMode {
    /// `σ = κ·σ_d(d)` (0.07 m up to 10 m, 0.21 m beyond with κ = 7).
    Datasheet,
    /// `σ_n = κ·max(floor, sample std of beam n during warm-up)`; the datasheet value is used
    /// until warm-up ends.
    Learned {
        /// Lower bound on the learned std, metres (0.005 in the spec).
        floor: f64,
    },
}

/// Long-term per-beam background (the revealed-background rule, spec §2.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LongTermConfig {
    /// Warm-up length in scans (`T_warm` = 5 s = 200 scans at 40 Hz).
    pub warm_scans: usize,
    /// A beam needs at least this fraction of valid warm-up readings for a background.
    pub min_valid_fraction: f64,
    /// Update rate `α_b`.
    pub alpha: f64,
    /// Relearn after this many consecutive static scans away from `b_n` (`T_relearn` = 2 s = 80).
    pub relearn_scans: u32,
    /// Update `b_n` only from static readings consistent with it (`|d − b_n| ≤ τ_g(d)`).
    ///
    /// The spec's literal update follows every static-labelled reading, including readings on a
    /// slow or briefly still person that pass (5)–(6); `b_n` then drifts toward people and the
    /// override misses the wall when it reappears (ghost tracks). The spec's own relearn rule
    /// covers genuine background changes, so the update may be restricted to readings that
    /// already agree with `b_n` (default `true`; `false` reproduces the ungated rule).
    pub gated_update: bool,
    /// Beams that return only now and then (not in spec 003; `false` = the spec): a beam with
    /// fewer than `min_valid_fraction` valid warm-up readings still gets a `b_n` when at least
    /// half of its valid warm-up readings, and at least two, lie within `τ_g` of their median
    /// (`b_n` = that median). A dark, shiny or distant surface that returns in a quarter of the
    /// scans at one range is background; without a `b_n` such a beam is dynamic by rule (3)
    /// whenever it returns, and its returns become leg-sized clusters that never move
    /// (docs/lidar-people.md, "Beams that return now and then").
    pub sparse_beams: bool,
}

impl Default for LongTermConfig {
    fn default() -> Self {
        Self {
            warm_scans: 200,
            min_valid_fraction: 0.5,
            alpha: 0.02,
            relearn_scans: 80,
            gated_update: true,
            sparse_beams: false,
        }
    }
}

/// Parameters of [`ChiSquareBackground`] (spec 003 §3). `Default` is the `faithful` preset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChiSquareConfig {
    /// Window length `m` (scans).
    pub window: usize,
    /// Static-probability threshold `P_th`.
    pub p_threshold: f64,
    /// Tolerance factor κ.
    pub kappa: f64,
    /// How σ is chosen.
    pub sigma: SigmaMode,
    /// Apply the region constraint (6).
    pub region_constraint: bool,
    /// Region radius δ, metres.
    pub region_radius: f64,
    /// The long-term background; `None` in the `literal` preset.
    pub long_term: Option<LongTermConfig>,
    /// Early start (not in spec 003; `None` = off, the spec's behaviour): while the window
    /// is still filling (the first `window / 2` scans), a beam with fewer than `window / 2`
    /// valid readings is compared with the *farthest* reading it has returned so far instead
    /// of being dynamic by rule (3). A reading this many metres or more in front of that
    /// farthest reading is dynamic, every other reading static; a beam that has returned
    /// nothing yet (the first scan) is static, and one whose earlier readings include a
    /// no-return is taken to have seen nothing there, so any return in it is dynamic. The
    /// background behind a walking person is revealed as they walk, so a scanner switched on
    /// among walking people sees them from its second scan instead of after `window / 2`
    /// scans. A person standing still from the start is background, as with rule (3) once
    /// the window is full. From scan `window / 2` on the spec's tests apply unchanged, but the
    /// window keeps the farthest reading (or a no-return) in place of each early reading it
    /// found dynamic: kept as read, the walker's ranges would hold the window mean in front of
    /// the wall behind them, and the wall would turn dynamic at scan `window / 2` (a ghost
    /// walking along the wall, seen on the leg-height recordings; see docs/lidar-people.md).
    pub early_start: Option<f64>,
}

impl Default for ChiSquareConfig {
    fn default() -> Self {
        Self {
            window: 40,
            p_threshold: 0.9,
            kappa: 7.0,
            sigma: SigmaMode::Datasheet,
            region_constraint: true,
            region_radius: 0.30,
            long_term: Some(LongTermConfig::default()),
            early_start: None,
        }
    }
}

impl ChiSquareConfig {
    /// The `literal` preset: no long-term background.
    pub fn literal() -> Self {
        Self {
            long_term: None,
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<()> {
        if self.window < 2 {
            return Err(CoreError::invalid("window", "need m >= 2").into());
        }
        if !(self.p_threshold > 0.0 && self.p_threshold < 1.0) {
            return Err(CoreError::invalid("p_threshold", "must be in (0, 1)").into());
        }
        if !(self.kappa.is_finite() && self.kappa > 0.0) {
            return Err(CoreError::invalid("kappa", "must be finite and positive").into());
        }
        if !(self.region_radius.is_finite() && self.region_radius >= 0.0) {
            return Err(CoreError::invalid("region_radius", "must be finite and >= 0").into());
        }
        if let Some(tol) = self.early_start
            && !(tol.is_finite() && tol > 0.0)
        {
            return Err(CoreError::invalid("early_start", "must be finite and positive").into());
        }
        if let SigmaMode::Learned { floor } = self.sigma
            && !(floor.is_finite() && floor > 0.0)
        {
            return Err(CoreError::invalid("sigma floor", "must be finite and positive").into());
        }
        if let Some(lt) = self.long_term {
            if lt.warm_scans == 0 {
                return Err(CoreError::invalid("warm_scans", "must be >= 1").into());
            }
            if !(lt.alpha >= 0.0 && lt.alpha <= 1.0) {
                return Err(CoreError::invalid("alpha", "must be in [0, 1]").into());
            }
            if !(lt.min_valid_fraction >= 0.0 && lt.min_valid_fraction <= 1.0) {
                return Err(CoreError::invalid("min_valid_fraction", "must be in [0, 1]").into());
            }
        }
        Ok(())
    }
}

/// Per-scan diagnostics of the last [`ChiSquareBackground::classify`] call.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanDiagnostics {
    /// `D²` per beam (NaN where not computed: invalid beam or too few valid window entries).
    pub d2: Vec<f64>,
    /// Preliminary candidate flags.
    pub candidate: Vec<bool>,
    /// Beams made static by the long-term override.
    pub overridden: usize,
}

/// The most ranges a [`ChiSquareBackground`] stores (window and warm-up rings over all beams):
/// 2²⁶ 16-bit ranges, 128 MiB. A real scanner with a 40-scan window needs a few hundred thousand;
/// a malformed geometry asking for billions is an error instead of an allocation failure.
pub const MAX_MODEL_CELLS: usize = 1 << 26;

/// The chi-square background model; implements [`BackgroundModel`].
#[derive(Debug, Clone)]
pub struct ChiSquareBackground {
    cfg: ChiSquareConfig,
    table: BeamTable,
    /// Ring buffer, beam-major: `ring[n * m + k]`, range in mm (0 = invalid).
    ring: Vec<u16>,
    sum_mm: Vec<u64>,
    n_valid: Vec<u32>,
    head: usize,
    scans: u64,
    last_t: Option<TimeUs>,
    // long-term background
    warm: Vec<u16>,
    background: Vec<Option<f64>>,
    static_run: Vec<u32>,
    // early start: per beam the farthest range returned so far (mm, 0 = none yet) and whether
    // the beam has ever returned nothing; empty without early start
    farthest: Vec<u16>,
    no_return: Vec<bool>,
    learned_sigma: Option<Vec<f64>>,
    diag: ScanDiagnostics,
}

impl ChiSquareBackground {
    /// A model for scans of `geometry`.
    pub fn new(geometry: &ScanGeometry, cfg: ChiSquareConfig) -> Result<Self> {
        cfg.validate()?;
        // checked before the beam table, which itself holds two numbers per beam
        let n = geometry.n_beams as usize;
        let warm_scans = cfg.long_term.map_or(0, |lt| lt.warm_scans);
        cfg.window
            .checked_add(warm_scans)
            .and_then(|per_beam| per_beam.checked_mul(n))
            .filter(|c| *c <= MAX_MODEL_CELLS)
            .ok_or_else(|| {
                CoreError::invalid(
                    "geometry",
                    format!(
                        "{n} beams x (window {} + warm-up {warm_scans} scans) ranges exceed the \
                         model's limit of {MAX_MODEL_CELLS} stored ranges",
                        cfg.window
                    ),
                )
            })?;
        let table = BeamTable::new(geometry)?;
        let warm_len = warm_scans * n;
        Ok(Self {
            cfg,
            table,
            ring: vec![0; n * cfg.window],
            sum_mm: vec![0; n],
            n_valid: vec![0; n],
            head: 0,
            scans: 0,
            last_t: None,
            warm: vec![0; warm_len],
            background: vec![None; n],
            static_run: vec![0; n],
            farthest: if cfg.early_start.is_some() {
                vec![0; n]
            } else {
                Vec::new()
            },
            no_return: if cfg.early_start.is_some() {
                vec![false; n]
            } else {
                Vec::new()
            },
            learned_sigma: None,
            diag: ScanDiagnostics::default(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &ChiSquareConfig {
        &self.cfg
    }

    /// Number of scans seen.
    pub fn scans_seen(&self) -> u64 {
        self.scans
    }

    /// True while the long-term background is still being learned (the wire's `BG_WARMING`).
    pub fn is_warming(&self) -> bool {
        self.cfg
            .long_term
            .is_some_and(|lt| self.scans < lt.warm_scans as u64)
    }

    /// The long-term background range `b_n` per beam, metres (`None` where unknown).
    pub fn long_term_background(&self) -> &[Option<f64>] {
        &self.background
    }

    /// Diagnostics of the last classified scan.
    pub fn diagnostics(&self) -> &ScanDiagnostics {
        &self.diag
    }

    /// The early-start test of beam `n` with reading `r` (see [`ChiSquareConfig::early_start`]):
    /// `None` when the reading is static, else the range (mm) the window keeps in its place —
    /// the farthest reading so far, or 0 (no return) when the beam once returned nothing.
    fn early_test(&self, n: usize, r: f64, tol: f64) -> Option<u16> {
        if self.no_return[n] {
            return Some(0);
        }
        let farthest = self.farthest[n];
        if farthest == 0 {
            return None; // the first scan: nothing known
        }
        (r <= f64::from(farthest) * 1e-3 - tol).then_some(farthest)
    }

    /// Early start, after labelling: records the farthest range and no-returns of every beam
    /// and, while the window holds every scan so far, replaces the window's readings that a
    /// new farthest reading shows to lie `tol` or more in front of the background.
    fn early_update(&mut self, scan: &PolarScan, tol: f64) {
        let m = self.cfg.window;
        let all_in_window = 2 * self.scans < m as u64;
        for n in 0..self.table.len() {
            if scan.range_m(n).is_none() {
                self.no_return[n] = true;
                continue;
            }
            let mm = scan.ranges_mm[n];
            if mm <= self.farthest[n] {
                continue;
            }
            self.farthest[n] = mm;
            if all_in_window && !self.no_return[n] {
                let cut = f64::from(mm) * 1e-3 - tol;
                for k in 0..self.scans as usize {
                    let slot = n * m + k;
                    let old = self.ring[slot];
                    if old != 0 && f64::from(old) * 1e-3 <= cut {
                        self.sum_mm[n] += u64::from(mm - old);
                        self.ring[slot] = mm;
                    }
                }
            }
        }
    }

    fn sigma(&self, n: usize, d: f64) -> f64 {
        match (&self.cfg.sigma, &self.learned_sigma) {
            (SigmaMode::Learned { .. }, Some(s)) => s[n],
            _ => self.cfg.kappa * sigma_d(d),
        }
    }

    /// Labels every beam of `scan` and updates the model (see the module docs). Errors: wrong
    /// beam count, or a timestamp earlier than the previous scan's (the model is unchanged).
    pub fn classify_scan(&mut self, scan: &PolarScan) -> Result<Vec<BeamLabel>> {
        check_scan(scan, self.table.geometry())?;
        if let Some(t) = self.last_t
            && scan.t < t
        {
            return Err(CoreError::invalid(
                "scan.t",
                format!(
                    "timestamp {} us is earlier than the previous scan's {} us",
                    scan.t.0, t.0
                ),
            )
            .into());
        }
        let m = self.cfg.window;
        let n_beams = self.table.len();
        let ln_th = -2.0 * self.cfg.p_threshold.ln(); // P > P_th  <=>  D² < -2 ln P_th
        let early = self.cfg.early_start.filter(|_| 2 * self.scans < m as u64);
        let mut points: Vec<Option<Point2>> = vec![None; n_beams];
        let mut candidate = vec![false; n_beams];
        let mut d2s = vec![f64::NAN; n_beams];
        // early start: what the window keeps instead of a reading the early test found dynamic
        let mut imputed: Vec<Option<u16>> = if early.is_some() {
            vec![None; n_beams]
        } else {
            Vec::new()
        };
        for n in 0..n_beams {
            let Some(r) = scan.range_m(n) else { continue };
            let Some(p) = self.table.point(n, r) else {
                continue;
            };
            points[n] = Some(p);
            let nv = self.n_valid[n] as usize;
            if 2 * nv < m {
                if let Some(tol) = early {
                    imputed[n] = self.early_test(n, r, tol);
                    candidate[n] = imputed[n].is_none();
                }
                continue; // fewer than m/2 valid: no evidence of static (rule (3))
            }
            let mean_r = self.sum_mm[n] as f64 * 1e-3 / nv as f64;
            let mean = self.table.point(n, mean_r).unwrap_or(p);
            let s = self.sigma(n, r);
            let d2 = statistical_distance2(&p, &mean, s, s);
            d2s[n] = d2;
            candidate[n] = d2 < ln_th && static_probability(d2) > self.cfg.p_threshold;
        }
        let mut is_static = if self.cfg.region_constraint {
            region_constraint_scan(
                &points,
                &candidate,
                self.cfg.region_radius,
                self.table.geometry().angle_increment,
            )?
        } else {
            candidate.clone()
        };
        // the labels of (5)-(6) alone: the relearn rule counts these (see `update_long_term`)
        let window_static = if self.cfg.long_term.is_some() {
            is_static.clone()
        } else {
            Vec::new()
        };
        let mut overridden = 0;
        // early start: until b_n is learned, the farthest reading so far stands in for it
        if let Some(lt) = self.cfg.long_term
            && self.cfg.early_start.is_some()
            && self.scans < lt.warm_scans as u64
        {
            for n in 0..n_beams {
                if let Some(r) = scan.range_m(n)
                    && !is_static[n]
                    && !self.no_return[n]
                    && self.farthest[n] != 0
                    && (r - f64::from(self.farthest[n]) * 1e-3).abs() <= tau_g(r)
                {
                    is_static[n] = true;
                    overridden += 1;
                }
            }
        }
        if self.cfg.long_term.is_some() {
            for n in 0..n_beams {
                if let (Some(b), Some(r)) = (self.background[n], scan.range_m(n))
                    && !is_static[n]
                    && (r - b).abs() <= tau_g(r)
                {
                    is_static[n] = true;
                    overridden += 1;
                }
            }
        }
        let labels: Vec<BeamLabel> = (0..n_beams)
            .map(|n| match (points[n], is_static[n]) {
                (None, _) => BeamLabel::Invalid,
                (Some(_), true) => BeamLabel::Static,
                (Some(_), false) => BeamLabel::Dynamic,
            })
            .collect();
        self.update_long_term(scan, &is_static, &window_static);
        // the farthest readings serve the early test (first window / 2 scans) and stand in for
        // b_n until it is learned; after both, nothing reads them
        if let Some(tol) = self.cfg.early_start
            && (2 * self.scans < m as u64
                || self
                    .cfg
                    .long_term
                    .is_some_and(|lt| self.scans < lt.warm_scans as u64))
        {
            self.early_update(scan, tol);
        }
        // push the scan into the window
        for n in 0..n_beams {
            let slot = n * m + self.head;
            let old = self.ring[slot];
            if old != 0 {
                self.sum_mm[n] -= u64::from(old);
                self.n_valid[n] -= 1;
            }
            let new = match (imputed.get(n), points[n]) {
                (Some(Some(mm)), _) => *mm,
                (_, Some(_)) => scan.ranges_mm[n],
                (_, None) => 0,
            };
            self.ring[slot] = new;
            if new != 0 {
                self.sum_mm[n] += u64::from(new);
                self.n_valid[n] += 1;
            }
        }
        self.head = (self.head + 1) % m;
        self.scans += 1;
        self.last_t = Some(scan.t);
        self.diag = ScanDiagnostics {
            d2: d2s,
            candidate,
            overridden,
        };
        Ok(labels)
    }

    /// `is_static`: the final labels (after the override); `window_static`: the labels of
    /// (5)-(6) before it.
    ///
    /// The relearn run counts only beams that are static *by the window test*. A reading the
    /// override made static agrees with `b_n`, so it is no evidence that the background moved;
    /// counted (spec §2.2 read literally: "static" as the final label), a wall seen again after
    /// a person walked through its beam relearned `b_n` to the window mean, which still held the
    /// person's ranges, 0.2-0.5 m in front of the wall, and the wall then stayed foreground
    /// (docs/lidar-people.md, "Background relearn").
    fn update_long_term(&mut self, scan: &PolarScan, is_static: &[bool], window_static: &[bool]) {
        let Some(lt) = self.cfg.long_term else { return };
        let n_beams = self.table.len();
        let k = self.scans as usize;
        if k < lt.warm_scans {
            for n in 0..n_beams {
                self.warm[n * lt.warm_scans + k] = if scan.range_m(n).is_some() {
                    scan.ranges_mm[n]
                } else {
                    0
                };
            }
            if k + 1 == lt.warm_scans {
                self.finish_warm_up(&lt);
            }
            return;
        }
        let m = self.cfg.window;
        for n in 0..n_beams {
            let Some(d) = scan.range_m(n) else {
                self.static_run[n] = 0;
                continue;
            };
            if !is_static[n] {
                self.static_run[n] = 0;
                continue;
            }
            let nv = self.n_valid[n] as usize;
            let mean = (2 * nv >= m).then(|| self.sum_mm[n] as f64 * 1e-3 / nv as f64);
            // static by the override only: b_n is confirmed, not contradicted
            let away = window_static[n]
                && match (self.background[n], mean) {
                    (Some(b), Some(mean)) => (mean - b).abs() > tau_g(mean),
                    (None, Some(_)) => true,
                    _ => false,
                };
            if away {
                self.static_run[n] += 1;
            } else {
                self.static_run[n] = 0;
            }
            if self.static_run[n] >= lt.relearn_scans
                && let Some(mean) = mean
            {
                self.background[n] = Some(mean);
                self.static_run[n] = 0;
            } else if let Some(b) = self.background[n]
                && (!lt.gated_update || (d - b).abs() <= tau_g(d))
            {
                self.background[n] = Some((1.0 - lt.alpha) * b + lt.alpha * d);
            }
        }
    }

    fn finish_warm_up(&mut self, lt: &LongTermConfig) {
        let w = lt.warm_scans;
        let mut sig = Vec::with_capacity(self.table.len());
        for n in 0..self.table.len() {
            let mut v: Vec<u16> = self.warm[n * w..(n + 1) * w]
                .iter()
                .copied()
                .filter(|&x| x != 0)
                .collect();
            v.sort_unstable();
            let median_m = (!v.is_empty()).then(|| {
                let mm = if v.len() % 2 == 1 {
                    f64::from(v[v.len() / 2])
                } else {
                    0.5 * (f64::from(v[v.len() / 2 - 1]) + f64::from(v[v.len() / 2]))
                };
                mm * 1e-3
            });
            if let Some(med) = median_m {
                if v.len() as f64 >= lt.min_valid_fraction * w as f64 {
                    self.background[n] = Some(med);
                } else if lt.sparse_beams {
                    // a beam that returns now and then at one range: that range, if it is the
                    // range of at least half its returns (and of two or more)
                    let tol = tau_g(med);
                    let near = v
                        .iter()
                        .filter(|&&x| (f64::from(x) * 1e-3 - med).abs() <= tol)
                        .count();
                    if near >= 2 && 2 * near >= v.len() {
                        self.background[n] = Some(med);
                    }
                }
            }
            if let SigmaMode::Learned { floor } = self.cfg.sigma {
                let std = if v.len() >= 2 {
                    let mean = v.iter().map(|&x| f64::from(x) * 1e-3).sum::<f64>() / v.len() as f64;
                    (v.iter()
                        .map(|&x| (f64::from(x) * 1e-3 - mean).powi(2))
                        .sum::<f64>()
                        / (v.len() - 1) as f64)
                        .sqrt()
                } else {
                    0.0
                };
                sig.push(self.cfg.kappa * std.max(floor));
            }
        }
        if matches!(self.cfg.sigma, SigmaMode::Learned { .. }) {
            self.learned_sigma = Some(sig);
        }
        self.warm = Vec::new();
    }
}

impl BackgroundModel for ChiSquareBackground {
    fn classify(&mut self, scan: &PolarScan) -> Result<Vec<BeamLabel>, CoreError> {
        self.classify_scan(scan).map_err(CoreError::from)
    }

    /// `b_n` once the warm-up is over; `None` while warming and without a long-term
    /// background (`literal`).
    fn published_background(&self) -> Option<&[Option<f64>]> {
        (self.cfg.long_term.is_some() && !self.is_warming()).then_some(&self.background[..])
    }
}

/// The per-beam variance-learned one-sided chi-square test of the peer workload
/// (`peers/bench_chi2.py`): the window holds the last `m` ranges of each beam; with window mean
/// `μ` and variance `s² = max(var_ddof1, s_min²)`, a range `r` is foreground iff
/// `(r − μ)²/s² > threshold` and `r < μ`. Running sums make a test O(beams). This is a common
/// textbook variant kept for comparison; the paper's model is [`ChiSquareBackground`].
#[derive(Debug, Clone)]
pub struct VarianceChi2Test {
    m: usize,
    beams: usize,
    window: Vec<f64>,
    head: usize,
    sum: Vec<f64>,
    sumsq: Vec<f64>,
    /// Minimum variance `s_min²`.
    pub min_var: f64,
    /// Decision threshold on `(r − μ)²/s²` (10.83 = χ²₁(0.999) in the peer).
    pub threshold: f64,
}

impl VarianceChi2Test {
    /// A test whose window is initialised with `initial` (m rows of `beams` ranges, metres).
    pub fn new(initial: &[Vec<f64>], min_sigma: f64, threshold: f64) -> Result<Self> {
        let m = initial.len();
        if m < 2 {
            return Err(CoreError::invalid("window", "need at least 2 scans").into());
        }
        let beams = initial[0].len();
        let mut window = Vec::with_capacity(m * beams);
        for row in initial {
            quarry_core::ensure_len(row.len(), beams, "window scan")?;
            quarry_core::ensure_finite(row, "window ranges")?;
            window.extend_from_slice(row);
        }
        let mut sum = vec![0.0; beams];
        let mut sumsq = vec![0.0; beams];
        for row in initial {
            for (b, &r) in row.iter().enumerate() {
                sum[b] += r;
                sumsq[b] += r * r;
            }
        }
        Ok(Self {
            m,
            beams,
            window,
            head: 0,
            sum,
            sumsq,
            min_var: min_sigma * min_sigma,
            threshold,
        })
    }

    /// Foreground flags of `ranges` against the current window (does not update it).
    pub fn test(&self, ranges: &[f64], out: &mut Vec<bool>) -> Result<()> {
        quarry_core::ensure_len(ranges.len(), self.beams, "scan ranges")?;
        out.clear();
        let m = self.m as f64;
        out.extend(ranges.iter().enumerate().map(|(b, &r)| {
            let mu = self.sum[b] / m;
            let var = ((self.sumsq[b] - self.sum[b] * mu) / (m - 1.0)).max(self.min_var);
            let d = r - mu;
            d * d / var > self.threshold && d < 0.0
        }));
        Ok(())
    }

    /// Pushes a scan into the window (replacing the oldest).
    pub fn push(&mut self, ranges: &[f64]) -> Result<()> {
        quarry_core::ensure_len(ranges.len(), self.beams, "scan ranges")?;
        quarry_core::ensure_finite(ranges, "scan ranges")?;
        let row = &mut self.window[self.head * self.beams..(self.head + 1) * self.beams];
        for (b, (&r, old)) in ranges.iter().zip(row.iter_mut()).enumerate() {
            self.sum[b] += r - *old;
            self.sumsq[b] += r * r - *old * *old;
            *old = r;
        }
        self.head = (self.head + 1) % self.m;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use quarry_core::SensorId;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn an_absurd_beam_count_is_an_error_not_an_allocation() {
        let g = ScanGeometry {
            n_beams: 1 << 31,
            ..one_beam_geometry()
        };
        let e = ChiSquareBackground::new(&g, ChiSquareConfig::default()).unwrap_err();
        assert!(e.to_string().contains("beams"), "{e}");
        let ok = ScanGeometry {
            n_beams: 1081,
            ..one_beam_geometry()
        };
        ChiSquareBackground::new(&ok, ChiSquareConfig::default()).unwrap();
    }

    fn one_beam_geometry() -> ScanGeometry {
        ScanGeometry {
            n_beams: 1,
            angle_min: 0.3,
            angle_increment: 0.01,
            range_min: 0.1,
            range_max: 30.0,
            scan_period: 0.025,
        }
    }

    fn scan1(seq: u32, mm: u16) -> PolarScan {
        PolarScan::try_new(
            SensorId(0),
            seq,
            TimeUs(i64::from(seq) * 25_000),
            vec![mm],
            one_beam_geometry(),
        )
        .unwrap()
    }

    fn simpson(d2: f64) -> f64 {
        let n = 10_000;
        let h = d2 / n as f64;
        let mut s = chi2_2dof_pdf(0.0) + chi2_2dof_pdf(d2);
        for i in 1..n {
            s += chi2_2dof_pdf(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        s * h / 3.0
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn static_probability_is_exp(d2 in 0.0f64..40.0) {
            prop_assert!((static_probability(d2) - (-d2 / 2.0).exp()).abs() < 1e-12);
            prop_assert!((static_probability(d2) - (1.0 - simpson(d2))).abs() < 1e-9);
            prop_assert_eq!(static_probability(d2) > 0.9, d2 < 0.210_721_031_315_652_6);
        }

        #[test]
        fn eq3_matrix_form_equals_range_form(
            window in prop::collection::vec(1.0f64..20.0, 2..40), d in 0.5f64..25.0,
            phi in -3.0f64..3.0, sigma in 0.01f64..0.3,
        ) {
            let mean = window.iter().sum::<f64>() / window.len() as f64;
            let (s, c) = phi.sin_cos();
            let p = Point2::new(d * c, d * s);
            // mean of the window *points* (not of the ranges)
            let pm = window.iter().fold(Point2::origin(), |a, r| Point2::new(a.x + r * c, a.y + r * s));
            let pm = Point2::new(pm.x / window.len() as f64, pm.y / window.len() as f64);
            let direct = statistical_distance2(&p, &pm, sigma, sigma);
            let reduced = (d - mean).powi(2) / (sigma * sigma);
            prop_assert!((direct - reduced).abs() <= 1e-9 * reduced.max(1e-12));
        }
    }

    #[test]
    fn static_beam_is_static_in_995_permille() {
        let mut bg = ChiSquareBackground::new(
            &one_beam_geometry(),
            ChiSquareConfig {
                region_constraint: false,
                ..ChiSquareConfig::literal()
            },
        )
        .unwrap();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.010).unwrap();
        let (mut stat, mut total) = (0, 0);
        for k in 0..100_000u32 {
            let x: f64 = noise.sample(&mut rng);
            let mm = ((5.0 + x) * 1000.0).round() as u16;
            let l = bg.classify_scan(&scan1(k, mm)).unwrap()[0];
            if k >= 40 {
                total += 1;
                stat += usize::from(l == BeamLabel::Static);
            }
        }
        let frac = stat as f64 / total as f64;
        assert!(frac >= 0.995, "static fraction {frac}");
    }

    #[test]
    fn receding_target_is_dynamic() {
        let mut bg = ChiSquareBackground::new(
            &one_beam_geometry(),
            ChiSquareConfig {
                region_constraint: false,
                ..ChiSquareConfig::literal()
            },
        )
        .unwrap();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
        let noise = Normal::new(0.0, 0.010).unwrap();
        let (mut dynamic, mut total) = (0, 0);
        for k in 0..2000u32 {
            let d = 2.0 + 0.10 * 0.025 * f64::from(k) + noise.sample(&mut rng);
            let l = bg
                .classify_scan(&scan1(k, (d * 1000.0).round() as u16))
                .unwrap()[0];
            if k >= 40 {
                total += 1;
                dynamic += usize::from(l == BeamLabel::Dynamic);
            }
        }
        let frac = dynamic as f64 / total as f64;
        assert!(frac >= 0.95, "dynamic fraction {frac}");
    }

    #[test]
    fn revealed_background_faithful_vs_literal() {
        // a wall at 5 m, a person at 2 m for 30 scans (< m), then the wall again
        let mk = |cfg: ChiSquareConfig| {
            ChiSquareBackground::new(
                &one_beam_geometry(),
                ChiSquareConfig {
                    region_constraint: false,
                    long_term: cfg.long_term.map(|lt| LongTermConfig {
                        warm_scans: 100,
                        ..lt
                    }),
                    ..cfg
                },
            )
            .unwrap()
        };
        for (cfg, max_scans) in [
            (ChiSquareConfig::default(), 1u32),
            (ChiSquareConfig::literal(), 41),
        ] {
            let mut bg = mk(cfg);
            let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
            let noise = Normal::new(0.0, 0.010).unwrap();
            let mut k = 0u32;
            let mut next = |bg: &mut ChiSquareBackground, d: f64| {
                k += 1;
                bg.classify_scan(&scan1(
                    k,
                    ((d + noise.sample(&mut rng)) * 1000.0).round() as u16,
                ))
                .unwrap()[0]
            };
            for _ in 0..300 {
                next(&mut bg, 5.0);
            }
            for _ in 0..30 {
                assert_eq!(next(&mut bg, 2.0), BeamLabel::Dynamic);
            }
            let mut until = 0;
            for i in 1..=100 {
                if next(&mut bg, 5.0) == BeamLabel::Static {
                    until = i;
                    break;
                }
            }
            assert!(
                until >= 1 && until <= max_scans,
                "static again after {until} scans (max {max_scans})"
            );
        }
    }

    proptest! {
        #[test]
        fn region_scan_equals_kd_version(
            n_beams in 2usize..200,
            fov_deg in 10.0f64..360.0,
            seed in 0u64..1000,
            delta in 0.05f64..1.0,
            non_candidate in prop_oneof![Just(0.3f64), 0.0f64..0.05],
        ) {
            // non_candidate: the share of valid points that are not candidates; the small ones
            // exercise the windows without any (decided without distance checks)
            let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
            let inc = fov_deg.to_radians() / n_beams as f64;
            let amin = -fov_deg.to_radians() / 2.0;
            let u = rand_distr::Uniform::new(0.0f64, 1.0).unwrap();
            // walls with steps, a few invalid beams, some points near the sensor
            let mut r = 0.1 + 5.0 * u.sample(&mut rng);
            let mut pts = Vec::new();
            let mut cand = Vec::new();
            for k in 0..n_beams {
                if u.sample(&mut rng) < 0.1 {
                    r = 0.05 + 6.0 * u.sample(&mut rng);
                }
                r += 0.02 * (u.sample(&mut rng) - 0.5);
                let a = amin + inc * k as f64;
                pts.push((u.sample(&mut rng) > 0.05).then(|| Point2::new(r * a.cos(), r * a.sin())));
                cand.push(u.sample(&mut rng) >= non_candidate && pts[k].is_some());
            }
            let a = region_constraint(&pts, &cand, delta).unwrap();
            let b = region_constraint_scan(&pts, &cand, delta, inc).unwrap();
            prop_assert_eq!(a, b);
        }
    }

    fn early_model(
        early_start: Option<f64>,
        long_term: Option<LongTermConfig>,
    ) -> ChiSquareBackground {
        ChiSquareBackground::new(
            &one_beam_geometry(),
            ChiSquareConfig {
                region_constraint: false,
                long_term,
                early_start,
                ..ChiSquareConfig::default()
            },
        )
        .unwrap()
    }

    /// Early start: the first scan is static (nothing known), a person walking out of the beam
    /// reveals the wall, a reading 0.10 m or more in front of the farthest one is dynamic, and a
    /// beam that once returned nothing makes any later return dynamic. Without it every reading
    /// of the first `window / 2` scans is dynamic (rule (3)).
    #[test]
    fn early_start_sees_a_walker_from_the_second_scan() {
        // window 40: the early phase is scans 0..20
        let ranges: [(u16, BeamLabel); 6] = [
            (1500, BeamLabel::Static), // scan 0: a person in the beam, nothing known yet
            (5000, BeamLabel::Static), // the person walked on: the wall
            (1500, BeamLabel::Dynamic), // the person back in the beam
            (4950, BeamLabel::Static), // the wall, 5 cm short of its farthest reading
            (4890, BeamLabel::Dynamic), // 11 cm short of it
            (5000, BeamLabel::Static),
        ];
        let mut bg = early_model(Some(0.10), None);
        let mut spec = early_model(None, None);
        for (k, (mm, want)) in ranges.into_iter().enumerate() {
            let s = scan1(k as u32, mm);
            assert_eq!(bg.classify_scan(&s).unwrap()[0], want, "scan {k}");
            assert_eq!(
                spec.classify_scan(&s).unwrap()[0],
                BeamLabel::Dynamic,
                "scan {k}"
            );
        }
        // the walker's early readings do not hold the window in front of the wall: at scan 20
        // (the window test from here on) the wall is static with early start; without it the
        // window mean holds the walker and the wall is dynamic
        for (early, want) in [(Some(0.10), BeamLabel::Static), (None, BeamLabel::Dynamic)] {
            let mut bg = early_model(early, None);
            for k in 0..20 {
                bg.classify_scan(&scan1(k, if k % 4 == 1 { 5000 } else { 1500 }))
                    .unwrap();
            }
            assert_eq!(
                bg.classify_scan(&scan1(20, 5000)).unwrap()[0],
                want,
                "{early:?}"
            );
        }
        let mut bg = early_model(Some(0.10), None);
        bg.classify_scan(&scan1(0, 5000)).unwrap();
        bg.classify_scan(&scan1(1, 0)).unwrap(); // no return
        assert_eq!(
            bg.classify_scan(&scan1(2, 5000)).unwrap()[0],
            BeamLabel::Dynamic
        );
        // a bad tolerance is refused
        for bad in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            let cfg = ChiSquareConfig {
                early_start: Some(bad),
                ..ChiSquareConfig::default()
            };
            assert!(
                ChiSquareBackground::new(&one_beam_geometry(), cfg).is_err(),
                "{bad}"
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Early start changes the window only through the first `window / 2` scans, so once
        /// those have left the window (scan `window / 2 + window` = 60) a model with it labels
        /// every reading as one without it, on any sequence of readings, valid or not.
        #[test]
        fn early_start_is_forgotten_once_its_scans_leave_the_window(
            mm in prop::collection::vec(prop_oneof![Just(0u16), 100u16..30_000, 4_900u16..5_100], 60..140),
            tol in 0.01f64..1.0,
        ) {
            let mut a = early_model(Some(tol), None);
            let mut b = early_model(None, None);
            for (k, &r) in mm.iter().enumerate() {
                let s = scan1(k as u32, r);
                let (la, lb) = (a.classify_scan(&s).unwrap(), b.classify_scan(&s).unwrap());
                if k >= 60 {
                    prop_assert_eq!(la, lb, "scan {}", k);
                }
            }
        }
    }

    /// One beam of the faithful model (no region constraint) that has seen a wall at 5 m for
    /// 150 scans.
    struct OneBeam {
        bg: ChiSquareBackground,
        k: u32,
    }

    impl OneBeam {
        fn after_a_wall(lt: LongTermConfig) -> Self {
            let bg = ChiSquareBackground::new(
                &one_beam_geometry(),
                ChiSquareConfig {
                    region_constraint: false,
                    long_term: Some(lt),
                    ..ChiSquareConfig::default()
                },
            )
            .unwrap();
            let mut beam = Self { bg, k: 0 };
            for _ in 0..150 {
                beam.next(5000);
            }
            beam
        }

        fn next(&mut self, mm: u16) -> BeamLabel {
            self.k += 1;
            self.bg.classify_scan(&scan1(self.k, mm)).unwrap()[0]
        }
    }

    /// `sparse_beams`: a beam that returns in one scan of four, always at 3 m (a dark surface),
    /// is background after the warm-up with it and dynamic at every return without it (rule
    /// (3): under half the window valid, and no `b_n`); a person at 1.5 m on that beam is
    /// dynamic either way; returns scattered over many ranges give no `b_n`.
    #[test]
    fn a_beam_that_returns_now_and_then_at_one_range_is_background() {
        fn model(sparse: bool) -> ChiSquareBackground {
            ChiSquareBackground::new(
                &one_beam_geometry(),
                ChiSquareConfig {
                    region_constraint: false,
                    long_term: Some(LongTermConfig {
                        warm_scans: 100,
                        sparse_beams: sparse,
                        ..LongTermConfig::default()
                    }),
                    ..ChiSquareConfig::default()
                },
            )
            .unwrap()
        }
        fn label(bg: &mut ChiSquareBackground, k: u32, mm: u16) -> BeamLabel {
            bg.classify_scan(&scan1(k, mm)).unwrap()[0]
        }
        for sparse in [false, true] {
            let mut bg = model(sparse);
            let mut after = Vec::new();
            for k in 0..200u32 {
                let l = label(&mut bg, k, if k % 4 == 0 { 3000 } else { 0 });
                if k >= 100 && k % 4 == 0 {
                    after.push(l);
                }
            }
            let expect = if sparse {
                BeamLabel::Static
            } else {
                BeamLabel::Dynamic
            };
            assert!(
                after.iter().all(|&l| l == expect),
                "sparse {sparse}: {after:?}"
            );
            assert_eq!(
                label(&mut bg, 200, 1500),
                BeamLabel::Dynamic,
                "sparse {sparse}"
            );
        }
        let mut bg = model(true);
        for k in 0..100u32 {
            let mm = if k % 4 == 0 {
                1000 + (k * 37 % 4000) as u16
            } else {
                0
            };
            label(&mut bg, k, mm);
        }
        assert_eq!(label(&mut bg, 100, 3000), BeamLabel::Dynamic);
    }

    /// The relearn run counts only window-test statics. With T_relearn shorter than the window
    /// (2 s at 10 Hz = 20 scans < m = 40, as on the leg-height recordings), a person crossing
    /// the beam for 5 scans leaves the window mean 0.46 m in front of the wall for 40 scans
    /// while the wall itself is static by the override; counted, those scans relearned b_n to
    /// that mean and the wall came back dynamic. An object that really stays is still learned.
    #[test]
    fn a_wall_seen_again_keeps_its_background_and_a_new_object_is_learned() {
        let mut beam = OneBeam::after_a_wall(LongTermConfig {
            warm_scans: 100,
            relearn_scans: 20,
            ..LongTermConfig::default()
        });
        for _ in 0..5 {
            assert_eq!(beam.next(1300), BeamLabel::Dynamic);
        }
        for i in 0..80 {
            assert_eq!(beam.next(5000), BeamLabel::Static, "wall scan {i}");
            let b = beam.bg.long_term_background()[0].unwrap();
            assert!((b - 5.0).abs() < 0.03, "b_n moved to {b} at wall scan {i}");
        }
        // a cupboard put in the beam at 3 m: static by the window test once the window holds
        // it, then learned after 20 such scans
        let mut learned = None;
        for i in 0..120 {
            beam.next(3000);
            if (beam.bg.long_term_background()[0].unwrap() - 3.0).abs() < 0.03 {
                learned = Some(i);
                break;
            }
        }
        let at = learned.expect("the cupboard became background");
        assert!((20..=60).contains(&at), "learned after {at} scans");
    }

    #[test]
    fn gated_update_keeps_background_under_a_still_person() {
        // wall at 5 m; a person stands at 3 m for 60 scans (static labels after the window
        // fills, but < T_relearn), then leaves. Gated: b_n stays on the wall and the wall is
        // static on the first scan. Ungated: b_n drifts toward 3 m and the wall comes back
        // dynamic.
        for (gated, expect_static) in [(true, true), (false, false)] {
            let lt = LongTermConfig {
                warm_scans: 100,
                gated_update: gated,
                ..LongTermConfig::default()
            };
            let mut beam = OneBeam::after_a_wall(lt);
            let mut statics = 0;
            for _ in 0..60 {
                if beam.next(3000) == BeamLabel::Static {
                    statics += 1;
                }
            }
            assert!(
                statics >= 15,
                "the still person became static {statics} times"
            );
            let b = beam.bg.long_term_background()[0].unwrap();
            if gated {
                assert!((b - 5.0).abs() < 1e-9, "gated b_n moved to {b}");
            } else {
                assert!(b < 4.9, "ungated b_n stayed at {b}");
            }
            assert_eq!(beam.next(5000) == BeamLabel::Static, expect_static);
        }
    }

    #[test]
    fn region_rules() {
        let p = |x: f64| Some(Point2::new(x, 0.0));
        // 10 candidates with 15 dynamic neighbours within delta => all dynamic
        let pts: Vec<Option<Point2>> = (0..25).map(|i| p(f64::from(i) * 0.001)).collect();
        let cand: Vec<bool> = (0..25).map(|i| i < 10).collect();
        assert!(
            region_constraint(&pts, &cand, 0.3)
                .unwrap()
                .iter()
                .all(|s| !s)
        );
        // static majority => static
        let cand: Vec<bool> = (0..25).map(|i| i < 15).collect();
        let out = region_constraint(&pts, &cand, 0.3).unwrap();
        assert!(out[..15].iter().all(|s| *s) && out[15..].iter().all(|s| !s));
        // tie => dynamic: candidate 0 with 1 candidate and 1 non-candidate neighbour
        let pts3 = vec![p(0.0), p(0.1), p(-0.1)];
        let out = region_constraint(&pts3, &[true, true, false], 0.15).unwrap();
        assert!(!out[0]);
        // empty neighbourhood => static; invalid beams are ignored
        let out = region_constraint(&[p(0.0), None, p(5.0)], &[true, false, false], 0.3).unwrap();
        assert_eq!(out, vec![true, false, false]);
    }

    #[test]
    fn bad_input_is_rejected() {
        let mut bg =
            ChiSquareBackground::new(&ScanGeometry::utm30lx(), ChiSquareConfig::default()).unwrap();
        let bad = PolarScan {
            sensor: SensorId(0),
            seq: 0,
            t: TimeUs(0),
            ranges_mm: vec![1000; 10],
            geometry: ScanGeometry::utm30lx(),
        };
        assert!(bg.classify(&bad).is_err());
        let ok = PolarScan::try_new(
            SensorId(0),
            1,
            TimeUs(100),
            vec![1000; 1081],
            ScanGeometry::utm30lx(),
        )
        .unwrap();
        assert_eq!(bg.classify(&ok).unwrap().len(), 1081);
        let back = PolarScan {
            t: TimeUs(50),
            ..ok
        };
        assert!(bg.classify(&back).is_err());
        assert_eq!(bg.scans_seen(), 1);
        assert!(
            ChiSquareBackground::new(
                &ScanGeometry::utm30lx(),
                ChiSquareConfig {
                    window: 1,
                    ..ChiSquareConfig::default()
                }
            )
            .is_err()
        );
    }

    #[test]
    fn variance_test_flags_closer_ranges() {
        let init: Vec<Vec<f64>> = (0..20)
            .map(|k| vec![5.0 + 0.001 * f64::from(k % 3), 3.0])
            .collect();
        let mut t = VarianceChi2Test::new(&init, 0.005, 10.83).unwrap();
        let mut out = Vec::new();
        t.test(&[4.0, 3.5], &mut out).unwrap();
        assert_eq!(out, vec![true, false]); // farther than the mean is not foreground
        t.push(&[4.0, 3.5]).unwrap();
        assert!(t.test(&[1.0], &mut out).is_err());
    }
}
