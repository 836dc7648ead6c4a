"""Type stubs for the quarry extension module (quarry's Rust building blocks from Python).

Arrays must be numpy arrays of the stated dtype, C-contiguous, of the stated shape; otherwise a
TypeError (type / dtype) or ValueError (shape, empty, layout, NaN / infinity) names the argument.
Errors of the Rust code are ValueErrors carrying its message.
"""
from os import PathLike
from typing import Literal, NotRequired, TypedDict

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]
I64 = npt.NDArray[np.int64]
I32 = npt.NDArray[np.int32]
U8 = npt.NDArray[np.uint8]

# ----------------------------------------------------------------------------------- filters

class KalmanFilter:
    """A linear Kalman filter holding x, P and the model (F, Q, H, R); float64 arrays.

    filterpy's KalmanFilter equations with the Joseph-form update. State dimensions 1-6 with
    measurement dimensions 1-4 run on fixed-size matrices (quarry-filter's EKF), other sizes on
    dynamic matrices.
    """

    def __init__(self, x: F64, P: F64, F: F64, Q: F64, H: F64, R: F64) -> None:
        """x (n,), P (n, n), F (n, n), Q (n, n), H (m, n), R (m, m)."""
    def predict(self) -> None:
        """x = F x, P = F P F' + Q."""
    def update(self, z: F64) -> None:
        """Update with z of shape (m,); the state is unchanged on error."""
    def step(self, z: F64) -> None:
        """predict() then update(z)."""
    def filter_sequence(self, zs: F64) -> F64:
        """Filter a (T, m) measurement array (GIL released); returns the (T, n) posterior means.

        Once P reaches its floating-point fixed point only the mean is propagated (the output is
        bit-identical to calling step() T times)."""
    @property
    def x(self) -> F64:
        """The state mean, (n,)."""
    @property
    def P(self) -> F64:
        """The state covariance, (n, n)."""

def ekf_predict(
    x: F64,
    P: F64,
    dt: float,
    motion: Literal["cv2", "cv3", "linear"] = "cv2",
    q: float | None = None,
    sigma_a: float | None = None,
    F: F64 | None = None,
    Q: F64 | None = None,
) -> tuple[F64, F64]:
    """EKF / KF time update of (x, P); returns the new (x, P).

    "cv2": state [x, y, vx, vy]; "cv3": [x, y, z, vx, vy, vz]; noise q (continuous white-noise
    acceleration, Stone Soup's ConstantVelocity(q)) or sigma_a (discrete). "linear": F and Q."""

def ekf_update(
    x: F64,
    P: F64,
    z: F64,
    measurement: Literal["position2", "position3", "range_bearing", "linear"] = "position2",
    R: F64 | None = None,
    H: F64 | None = None,
    sensor: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> tuple[F64, F64, float, float]:
    """EKF / KF measurement update (Joseph form); returns (x, P, nis, log_likelihood).

    "position2": z = (x, y) of a state of dimension 2, 4 or 6; "position3": (x, y, z) of 3, 5
    or 6; "range_bearing": (range, bearing) of the point (x[0], x[1]) from a sensor pose
    (sx, sy, stheta), state 2 or 4, bearing residual wrapped; "linear": H (m, n) and R (m, m)."""

def normalise_log_weights(log_w: F64) -> tuple[F64, float]:
    """(weights summing to 1, log of the sum of exp(log_w)); -inf entries allowed."""

def effective_sample_size(weights: F64) -> float:
    """1 / sum(w**2) of normalised weights."""

def resample(
    weights: F64,
    seed: int,
    scheme: Literal["systematic", "stratified", "multinomial", "residual"] = "systematic",
) -> I64:
    """Ancestor indices (N,) drawn from non-negative weights (N,); reproducible from the seed."""

def particle_filter_cv2(
    particles: F64,
    zs: F64,
    dt: float,
    q: float,
    R: F64,
    seed: int,
    scheme: Literal["systematic", "stratified", "multinomial", "residual"] = "systematic",
    ess_threshold: float = 1.0,
) -> F64:
    """Bootstrap particle filter, planar constant velocity + position likelihood.

    particles (N, 4) [x, y, vx, vy], zs (T, 2), R (2, 2); resample when ESS < ess_threshold * N
    (1.0 = every step). Returns the (T, 4) weighted means."""

# ------------------------------------------------------------------------------- association

def chi2_threshold(prob_gate: float, dim: int) -> float:
    """gamma = chi2.ppf(prob_gate, dim), the gate threshold on the squared Mahalanobis distance."""

def chi2_gate(zhat: F64, S: F64, z: F64, prob_gate: float = 0.99) -> tuple[F64, F64]:
    """Gate n predictions (zhat (n, d), S (n, d, d)) against m detections z (m, d), d in 1-4.

    Returns (d2, loglik), both (n, m): squared Mahalanobis distances, and ln N(z; zhat, S)
    inside the gate, -inf outside (the input of pda / jpda / jipda / gnn)."""

def pda(
    loglik: F64, pd: float, prob_gate: float, clutter_density: float, detection: F64 | None = None
) -> tuple[F64, float]:
    """PDA per track: (beta (n, m + 1) with column 0 = missed, log_normaliser)."""

def jpda(
    loglik: F64,
    pd: float,
    prob_gate: float,
    clutter_density: float,
    method: Literal["auto", "exact", "lbp", "kbest"] = "auto",
    k: int = 0,
    detection: F64 | None = None,
) -> tuple[F64, float]:
    """JPDA marginals: (beta (n, m + 1), column 0 = missed, rows sum to 1; log_normaliser)."""

def jipda(
    loglik: F64,
    existence: F64,
    pd: float,
    prob_gate: float,
    clutter_density: float,
    survival: float = 1.0,
    method: Literal["auto", "exact", "lbp", "kbest"] = "auto",
    k: int = 0,
    detection: F64 | None = None,
) -> tuple[F64, F64, float]:
    """JIPDA: (beta conditioned on existence (n, m + 1), posterior existence (n,), log_normaliser)."""

def gnn(
    loglik: F64,
    pd: float,
    prob_gate: float,
    clutter_density: float,
    cost: Literal["joint", "max_cardinality"] = "joint",
) -> tuple[I64, float]:
    """Global nearest neighbour: (row_to_col (n,), -1 = unassigned; total cost)."""

def assign(cost: F64, miss_cost: F64 | None = None) -> tuple[I64, float]:
    """Minimum-cost assignment (+inf = forbidden); with miss_cost (n,) a row may stay unassigned."""

def murty_k_best(cost: F64, k: int, miss_cost: F64 | None = None) -> tuple[I64, F64]:
    """The k best assignments: (row_to_col (k', n), costs (k',)), by increasing cost."""

# ----------------------------------------------------------------------------------- metrics

class MotSummary(TypedDict):
    mota: float
    moda: float
    motp: float
    recall: float
    precision: float
    num_frames: int
    num_objects: int
    num_predictions: int
    num_unique_objects: int
    num_matches: int
    num_switches: int
    num_false_positives: int
    num_misses: int
    num_fragmentations: int
    num_transfer: int
    num_ascend: int
    num_migrate: int
    mostly_tracked: int
    partially_tracked: int
    mostly_lost: int
    idf1: float
    idp: float
    idr: float
    idtp: int
    idfp: int
    idfn: int
    hota: float
    deta: float
    assa: float
    loca: float
    detre: float
    detpr: float
    assre: float
    asspr: float
    hota_alpha: F64
    hota_per_alpha: F64
    deta_per_alpha: F64
    assa_per_alpha: F64

def mot_metrics(
    gt: F64,
    hyp: F64,
    similarity: Literal["iou", "euclidean"] = "iou",
    threshold: float | None = None,
    zero_at: float | None = None,
) -> MotSummary:
    """CLEAR MOT (py-motmetrics), IDF1 and HOTA (TrackEval) of rows frame, id, values.

    "iou": (N, 6) rows frame, id, left, top, width, height; threshold default 0.5.
    "euclidean": (N, 4) frame, id, x, y or (N, 5) with z; threshold required, HOTA similarity
    max(0, 1 - d / zero_at), zero_at default 2 * threshold. NaN where a ratio is undefined."""

def mot_metrics_files(
    gt_path: str | PathLike[str],
    res_path: str | PathLike[str],
    threshold: float = 0.5,
    gt_style: Literal["auto", "mot15", "mot16"] = "auto",
) -> MotSummary:
    """The same from MOTChallenge ground-truth and results files (ignored GT handled)."""

class Gospa(TypedDict):
    distance: float
    localisation: float
    missed: int
    false_targets: int
    assigned: int

def ospa(x: F64, y: F64, c: float, p: float = 1.0) -> float:
    """OSPA distance between point sets x (m, d) and y (n, d), d in 1-4."""

def gospa(x: F64, y: F64, c: float, p: float = 1.0) -> Gospa:
    """GOSPA (alpha = 2) between the truth x (m, d) and the estimates y (n, d), decomposed."""

# ------------------------------------------------------------------------------------ vision

def gaussian_blur(img: F32 | F64, sigma: float) -> F32 | F64:
    """cv2.GaussianBlur(img, (0, 0), sigma, borderType=BORDER_REFLECT_101); same dtype out."""

def regional_minima(relief: F32 | F64 | U8, connectivity: Literal[4, 8] = 4) -> tuple[I32, int]:
    """(labels (H, W) int32, 1..n on the minima, 0 elsewhere; n)."""

def watershed(
    relief: F32 | F64 | U8, markers: I32 | None = None, connectivity: Literal[4, 8] = 4
) -> I32:
    """Meyer watershed without lines; seeds = markers (0 = none) or the regional minima."""

KeypointArray = np.ndarray  # dtype [('pt', '<f4', (2,)), ('size', '<f4'), ('angle', '<f4'),
#                                    ('response', '<f4'), ('octave', '<i4'), ('class_id', '<i4')]
MatchArray = np.ndarray  # dtype [('queryIdx', '<i4'), ('trainIdx', '<i4'), ('imgIdx', '<i4'),
#                                 ('distance', '<f4')]

class Sift:
    """SIFT following cv2.SIFT_create() (same defaults); images uint8 (H, W), at least 16 px."""

    def __init__(
        self,
        nfeatures: int = 0,
        n_octave_layers: int = 3,
        contrast_threshold: float = 0.04,
        edge_threshold: float = 10.0,
        sigma: float = 1.6,
    ) -> None: ...
    def detect(self, img: U8) -> KeypointArray:
        """Keypoints, a structured array with cv2.KeyPoint's fields."""
    def compute(self, img: U8, keypoints: KeypointArray) -> U8:
        """Descriptors (N, 128) uint8 of keypoints (ours or OpenCV's, same fields)."""
    def detect_and_compute(self, img: U8) -> tuple[KeypointArray, U8]:
        """(keypoints, descriptors), building the scale space once."""

def match_sift(
    query: U8,
    train: U8,
    ratio: float | None = 0.8,
    max_distance: float | None = None,
    mutual: bool = False,
) -> MatchArray:
    """Brute-force L2 matches of (N, 128) uint8 descriptors with Lowe's ratio test."""

# ------------------------------------------------------------------------------ point clouds

def mean_shift(
    points: F64,
    bandwidth: float = 0.3,
    kernel: Literal["flat", "gaussian"] = "flat",
    seeding: Literal["bins", "all"] = "bins",
    min_cluster_size: int = 3,
    tolerance: float = 1e-3,
    max_iter: int = 50,
    merge_radius: float | None = None,
    noise_factor: float = 2.0,
) -> tuple[I64, F64, I64]:
    """MeanShift of (N, 2) points: (labels (N,), -1 = noise; modes (K, 2); sizes (K,))."""

def rigid_transform_2d(src: F64, dst: F64, weights: F64 | None = None) -> tuple[float, float, float]:
    """Least-squares (x, y, theta) mapping paired src (N, 2) onto dst (N, 2)."""

class IcpResult(TypedDict):
    pose: tuple[float, float, float]
    rms: float
    inliers: int
    iters: int
    converged: bool

def icp_2d(
    model: F64,
    data: F64,
    init: tuple[float, float, float] = (0.0, 0.0, 0.0),
    preset: Literal["default", "contour", "contour_point_to_line", "literal"] = "default",
    max_iter: int | None = None,
    rms_stop: float | None = None,
    delta_stop: float | None = None,
) -> IcpResult:
    """2-D ICP: the pose mapping model (M, 2) onto data (N, 2) from init."""

class ChiSquareBackground:
    """The chi-square background model of spec 003 for one laser scanner (angles in radians)."""

    def __init__(
        self,
        n_beams: int,
        angle_min: float,
        angle_increment: float,
        range_min: float = 0.1,
        range_max: float = 30.0,
        scan_period: float = 0.025,
        window: int = 40,
        p_threshold: float = 0.9,
        kappa: float = 7.0,
        region_constraint: bool = True,
        region_radius: float = 0.3,
        long_term: bool = True,
    ) -> None: ...
    def classify(self, ranges: F64, t: float) -> npt.NDArray[np.int8]:
        """Label one scan of (n_beams,) ranges in metres at time t (s): 0 static, 1 dynamic,
        2 invalid / learning."""
    @property
    def scans_seen(self) -> int: ...

class VarianceChi2Test:
    """The per-beam variance chi-square test of peers/bench_chi2.py."""

    def __init__(self, window: F64, min_sigma: float = 0.005, threshold: float = 10.83) -> None:
        """window (m, beams) ranges in metres, m >= 2."""
    def test(self, ranges: F64) -> npt.NDArray[np.bool_]:
        """Foreground flags (beams,) of ranges against the window."""
    def push(self, ranges: F64) -> None:
        """Push a scan into the window, replacing the oldest."""

# ---------------------------------------------------------------------------------- trackers

def track_video(
    frames: U8 | str | PathLike[str],
    preset: Literal["paper", "robust"] = "robust",
    person_size: tuple[float, float] | None = None,
    config_toml: str | None = None,
) -> F64:
    """The video tracker of spec 004 (watershed + SIFT pools) on frames (T, H, W) uint8 or a
    directory of PNG / JPEG frames (sorted by name, colour read as BT.601 grey).

    Returns rows frame, id, left, top, width, height (MOTChallenge convention, 1-based)."""

def track_lidar(
    scans: F64,
    stamps: F64,
    angle_min: float,
    angle_increment: float,
    range_min: float = 0.1,
    range_max: float = 30.0,
    scan_period: float = 0.025,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
    preset: Literal["faithful", "literal", "kf-gnn", "jipda"] = "faithful",
    config_toml: str | None = None,
    gap_factor: float = 3.0,
    backfill: bool = False,
) -> F64:
    """The laser people tracker of spec 003 on one scanner's scans (T, n_beams) in metres.

    backfill (offline; kf-gnn and jipda): once a track is reported, also report it at the
    earlier scans where it was detected but held back (tentative, or not yet walked).
    Returns rows scan, t, id, x, y, vx, vy, alpha, rms (world metres)."""

def track_rgbd(
    rgb: U8,
    depth: F32,
    init_box: tuple[float, float, float, float],
    preset: str = "paper",
    config_toml: str | None = None,
    fps: float = 30.0,
) -> F64:
    """The RGB-D person tracker of spec 001 (static camera) from an initial (left, top, w, h).

    rgb (T, H, W, 3) uint8, depth (T, H, W) float32 metres (0 / NaN = none). Returns one row
    per frame: frame (1-based), left, top, width, height (NaN when lost), state (0 normal ..
    5 lost)."""

class MrclamResult(TypedDict):
    tracks: F64
    robot_est: F64
    robot_true: F64
    epoch_t: F64
    map: F64
    ospa: float
    gospa: float
    map_err: float
    assoc_accuracy: float
    ate: float
    ms_per_step: float
    smoothed_est: NotRequired[F64]
    smoothed_map: NotRequired[F64]
    smoothed_robot_err: NotRequired[float]
    smoothed_map_err: NotRequired[float]
    smoothed_ate: NotRequired[float]
    calibration: NotRequired[list[float]]

def track_mrclam(
    directory: str | PathLike[str],
    robot: int = 1,
    particles: int = 50,
    seed: int = 0,
    max_frames: int | None = None,
    smooth: Literal["plain", "calibrated"] | None = None,
) -> MrclamResult:
    """The RBPF SLAM + JIPDA tracker of spec 000 on one robot of an MRCLAM dataset directory,
    scored against Vicon. tracks rows: t, id, x, y, vx, vy, existence. With smooth, the run is
    also refined by the batch smoother (the smoothed_* keys and calibration)."""
