"""The trackers from Python on synthetic sequences with known ground truth: the video tracker
(spec 004) on walking blobs, scored with quarry's own MOT metrics (checked against
py-motmetrics elsewhere); the laser tracker (spec 003) on ray-cast scans of a room with two
walking people."""
import math

import numpy as np
import pytest

import quarry


def blob_video(frames=30, w=192, h=96):
    """Two dark textured ellipses walking in opposite directions on a textured background;
    returns (frames (T, H, W) uint8, ground truth rows frame, id, left, top, width, height)."""
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    bg = 170.0 + 20.0 * np.sin(xx * 0.3) * np.cos(yy * 0.23)
    out, gt = [], []
    for k in range(frames):
        img = bg.copy()
        for pid, (cx, cy) in enumerate(((30.0 + 2.0 * k, 40.0), (160.0 - 2.0 * k, 60.0))):
            inside = ((xx - cx) / 6.0) ** 2 + ((yy - cy) / 14.0) ** 2 <= 1.0
            img[inside] = 60.0 + 15.0 * np.sin((xx[inside] + yy[inside]) * 0.9)
            gt.append([k + 1, pid + 1, cx - 6.0 + 1.0, cy - 15.0 + 1.0, 12.0, 30.0])
        out.append(np.clip(img, 0, 255).astype(np.uint8))
    return np.stack(out), np.array(gt)


def test_video_tracker_follows_walking_blobs():
    frames, gt = blob_video()
    rows = quarry.track_video(frames, preset="robust", person_size=(12.0, 30.0))
    assert rows.ndim == 2 and rows.shape[1] == 6 and len(rows) > 0
    assert set(np.unique(rows[:, 0])) <= set(range(1, len(frames) + 1))
    s = quarry.mot_metrics(gt, rows, similarity="iou", threshold=0.3)
    print(f"video tracker on blobs: {len(np.unique(rows[:, 1]))} ids, MOTA {s['mota']:.3f}, "
          f"IDF1 {s['idf1']:.3f}, recall {s['recall']:.3f}")
    # targets are born from moving points after a few frames of trajectory, then held
    assert s["recall"] > 0.5 and s["precision"] > 0.8 and s["num_switches"] <= 2
    # deterministic
    np.testing.assert_array_equal(rows, quarry.track_video(frames, preset="robust", person_size=(12.0, 30.0)))


def ray_box(ox, oy, dx, dy, x0, x1, y0, y1):
    """Distance along the ray to the axis-aligned box [x0, x1] x [y0, y1] (inf if missed)."""
    t_lo, t_hi = -np.inf, np.inf
    for o, d, lo, hi in ((ox, dx, x0, x1), (oy, dy, y0, y1)):
        if abs(d) < 1e-12:
            if o < lo or o > hi:
                return np.inf
            continue
        a, b = (lo - o) / d, (hi - o) / d
        t_lo, t_hi = max(t_lo, min(a, b)), min(t_hi, max(a, b))
    return t_lo if t_hi >= max(t_lo, 0) and t_lo > 0 else np.inf


def ray_ellipse(ox, oy, dx, dy, cx, cy, a, b, th):
    """Distance to an ellipse of semi-axes a, b rotated by th centred at (cx, cy)."""
    c, s = math.cos(th), math.sin(th)
    px, py = (ox - cx) * c + (oy - cy) * s, -(ox - cx) * s + (oy - cy) * c
    ux, uy = dx * c + dy * s, -dx * s + dy * c
    A = (ux / a) ** 2 + (uy / b) ** 2
    B = 2 * (px * ux / a**2 + py * uy / b**2)
    C = (px / a) ** 2 + (py / b) ** 2 - 1
    disc = B * B - 4 * A * C
    if disc < 0:
        return np.inf
    t = (-B - math.sqrt(disc)) / (2 * A)
    return t if t > 0 else np.inf


def laser_sequence(scans=120, beams=361, period=0.05, seed=0):
    """A scanner at (0.2, 0.2) looking into a 10 m x 8 m room (walls and a pillar); two people
    (ellipses 0.25 x 0.15 m) walk across after 40 empty scans. Returns scans (T, beams) metres,
    stamps, the beam geometry and the people's true positions per scan (NaN while absent)."""
    rng = np.random.default_rng(seed)
    angle_min, inc = -math.pi / 4, (math.pi / 2) / (beams - 1)  # 90 degrees centred on 45
    heading = math.pi / 4
    sx, sy = 0.2, 0.2
    out = np.zeros((scans, beams))
    truth = np.full((scans, 2, 2), np.nan)
    for k in range(scans):
        people = []
        if k >= 40:
            t = (k - 40) * period
            people = [(3.0 + 0.8 * t, 2.0 + 0.5 * t, math.atan2(0.5, 0.8)), (6.0 - 0.6 * t, 5.0, math.pi)]
            for i, (px, py, _) in enumerate(people):
                truth[k, i] = (px, py)
        for b in range(beams):
            ang = heading + angle_min + b * inc
            dx, dy = math.cos(ang), math.sin(ang)
            walls = [((10 if dx > 0 else 0) - sx) / dx if abs(dx) > 1e-9 else np.inf,
                     ((8 if dy > 0 else 0) - sy) / dy if abs(dy) > 1e-9 else np.inf]
            r = min(*walls, ray_box(sx, sy, dx, dy, 2.8, 3.2, 4.8, 5.2))
            for px, py, th in people:
                r = min(r, ray_ellipse(sx, sy, dx, dy, px, py, 0.25, 0.15, th))
            out[k, b] = r + rng.normal(0, 0.01)
    stamps = np.arange(scans) * period
    return out, stamps, (angle_min + heading, inc), truth


def test_lidar_tracker_follows_two_people():
    scans, stamps, (amin, inc), truth = laser_sequence()
    rows = quarry.track_lidar(scans, stamps, amin, inc, scan_period=0.05, pose=(0.2, 0.2, 0.0),
                              config_toml="window_m = 20")
    assert rows.shape[1] == 9 and len(rows) > 0
    # score: each tracked scan's tracks against the truth of that scan (OSPA, c = 1 m)
    errs, found = [], 0
    for k in range(60, len(scans)):
        est = rows[rows[:, 0] == k][:, 3:5]
        tru = truth[k]
        errs.append(quarry.ospa(tru, np.ascontiguousarray(est), 1.0, 1.0))
        if len(est):
            found += 1
    print(f"lidar tracker: {len(np.unique(rows[:, 2]))} ids, mean OSPA(c = 1 m) {np.mean(errs):.3f} m over "
          f"scans 60-{len(scans) - 1}, tracks in {found} of them")
    assert np.mean(errs) < 0.3
    assert len(rows[rows[:, 0] < 40]) == 0  # nobody in the room before scan 40


def test_lidar_backfill_reports_the_held_back_scans_of_the_same_tracks():
    scans, stamps, (amin, inc), _ = laser_sequence()
    kw = dict(scan_period=0.05, pose=(0.2, 0.2, 0.0), preset="kf-gnn", config_toml="window_m = 20")
    live = quarry.track_lidar(scans, stamps, amin, inc, **kw)
    back = quarry.track_lidar(scans, stamps, amin, inc, backfill=True, **kw)
    # the same tracks, each starting no later; the M-of-N confirmation scans come back
    assert set(np.unique(live[:, 2])) == set(np.unique(back[:, 2]))
    assert len(back) > len(live)
    for i in np.unique(live[:, 2]):
        assert back[back[:, 2] == i][:, 0].min() < live[live[:, 2] == i][:, 0].min()


def test_tracker_errors_name_the_argument():
    with pytest.raises(ValueError, match="preset"):
        quarry.track_video(np.zeros((3, 32, 32), np.uint8), preset="fast")
    with pytest.raises(ValueError, match="config_toml"):
        quarry.track_video(np.zeros((3, 32, 32), np.uint8), config_toml="no_such_key = 1")
    with pytest.raises(TypeError, match="frames"):
        quarry.track_video(np.zeros((3, 32, 32), np.float32))
    with pytest.raises(ValueError, match="frames"):
        quarry.track_video(np.zeros((32, 32), np.uint8))
    with pytest.raises(ValueError, match="person_size"):
        quarry.track_video(np.zeros((3, 32, 32), np.uint8), person_size=(-1.0, 10.0))
    with pytest.raises(ValueError, match="stamps"):
        quarry.track_lidar(np.zeros((5, 10)), np.zeros(4), 0.0, 0.1)
    with pytest.raises(ValueError, match="scans"):
        quarry.track_lidar(np.full((5, 10), np.nan), np.zeros(5), 0.0, 0.1)
    with pytest.raises(ValueError, match="config_toml"):
        quarry.track_lidar(np.zeros((5, 10)), np.arange(5.0), 0.0, 0.1, config_toml="bandwidth = -1")


def test_rgbd_tracker_follows_a_moving_person(bench_data):
    """bench-data's RGB-D frame, shifted 4 px right per frame: the box of person A follows."""
    import cv2
    rgb = cv2.cvtColor(cv2.imread(str(bench_data / "rgbd_rgb.png")), cv2.COLOR_BGR2RGB)
    depth = cv2.imread(str(bench_data / "rgbd_depth.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 1000
    T = 8
    R = np.stack([np.roll(rgb, 4 * k, axis=1) for k in range(T)])
    D = np.stack([np.roll(depth, 4 * k, axis=1) for k in range(T)])
    rows = quarry.track_rgbd(R, D, (60.0, 150.0, 100.0, 200.0))
    assert rows.shape == (T, 6)
    cx = rows[:, 1] + rows[:, 3] / 2
    err = np.abs(cx - (110 + 4 * np.arange(T)))
    print(f"rgbd tracker: centre x error per frame {np.round(err, 1)} px")
    assert np.all(err < 8.0) and np.all(rows[:, 5] == 0)
    D[3][:] = np.nan  # a frame without depth is not an error
    quarry.track_rgbd(R, D, (60.0, 150.0, 100.0, 200.0))
    with pytest.raises(ValueError, match="init_box"):
        quarry.track_rgbd(R, D, (5000.0, 150.0, 100.0, 200.0))
    with pytest.raises(ValueError, match="depth"):
        quarry.track_rgbd(R, D[:, :, :10], (60.0, 150.0, 100.0, 200.0))
    with pytest.raises(ValueError, match="depth"):
        quarry.track_rgbd(R, np.full_like(D, np.inf), (60.0, 150.0, 100.0, 200.0))


def test_slamot_on_mrclam_if_present(bench_data):
    """The spec 000 tracker on robot 1 of MRCLAM dataset 6 (the first 8000 frames, 20
    particles), through quarry_repro's runner: deterministic from the seed, the robot's own
    trajectory within decimetres of Vicon, a map and confirmed target tracks."""
    d = bench_data.parent / "data" / "mrclam-6"
    if not (d / "Barcodes.dat").exists():
        pytest.skip(f"{d} not found (optional data)")
    r = quarry.track_mrclam(d, robot=1, particles=20, seed=0, max_frames=8000)
    again = quarry.track_mrclam(str(d), robot=1, particles=20, seed=0, max_frames=8000)
    np.testing.assert_array_equal(r["robot_est"], again["robot_est"])
    np.testing.assert_array_equal(r["tracks"], again["tracks"])
    err = np.linalg.norm(r["robot_est"][:, :2] - r["robot_true"][:, :2], axis=1)
    print(f"MRCLAM-6 robot 1, 8000 frames: {len(err)} epochs, robot error mean {err.mean():.3f} m, "
          f"{len(r['map'])} landmarks (error {r['map_err']:.3f} m), {len(r['tracks'])} track rows, "
          f"OSPA {r['ospa']:.3f}")
    assert err.mean() < 0.5 and len(r["map"]) >= 3
    assert len(r["tracks"]) > 0 and np.all((r["tracks"][:, 6] >= 0) & (r["tracks"][:, 6] <= 1))
    with pytest.raises(ValueError, match="Barcodes|No such file|not found"):
        quarry.track_mrclam(d / "missing", robot=1)
    with pytest.raises(ValueError, match="particles"):
        quarry.track_mrclam(d, particles=0)
    with pytest.raises(ValueError, match="smooth"):
        quarry.track_mrclam(d, smooth="yes")


def test_slamot_smoothed_on_mrclam_if_present(bench_data):
    """The filter + batch smoother on the whole of robot 1 (docs/slamot.md: 0.156 m robot error,
    0.144 m map error, the same from every filter seed)."""
    d = bench_data.parent / "data" / "mrclam-6"
    if not (d / "Barcodes.dat").exists():
        pytest.skip(f"{d} not found (optional data)")
    r = quarry.track_mrclam(d, robot=1, particles=20, seed=3, smooth="plain")
    err = np.linalg.norm(r["smoothed_est"][:, :2] - r["robot_true"][:, :2], axis=1)
    print(f"smoothed: robot {err.mean():.3f} m (filter "
          f"{np.linalg.norm(r['robot_est'][:, :2] - r['robot_true'][:, :2], axis=1).mean():.3f}),"
          f" map {r['smoothed_map_err']:.3f} m")
    assert abs(err.mean() - r["smoothed_robot_err"]) < 1e-9
    assert err.mean() < 0.2 and r["smoothed_map_err"] < 0.2
    assert r["smoothed_est"].shape == r["robot_est"].shape and len(r["smoothed_map"]) == 15
    assert r["calibration"] == [1.0, 1.0, 0.0, 0.0]


def test_lidar_stamps_beyond_range_are_errors():
    """Found by test_fuzz: a stamp of 1e300 s saturated to i64 microseconds and overflowed the
    tracker's time difference (a Rust panic); the binding now refuses such stamps."""
    with pytest.raises(ValueError, match="stamps"):
        quarry.track_lidar(np.ones((3, 9)), np.array([0.0, 1e300, -1e300]), 0.0, 0.1)
    with pytest.raises(ValueError, match="t"):
        quarry.ChiSquareBackground(9, 0.0, 0.1).classify(np.ones(9), 1e13)


def test_video_tracker_reads_a_frame_directory(tmp_path):
    """A MOTChallenge-style img1/ directory gives the same tracks as the same frames in an array."""
    import cv2
    frames, _ = blob_video(frames=20)
    for k, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"{k + 1:06d}.png"), f)
    from_dir = quarry.track_video(tmp_path, person_size=(12.0, 30.0))
    np.testing.assert_array_equal(from_dir, quarry.track_video(frames, person_size=(12.0, 30.0)))
    assert len(from_dir) > 0
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(ValueError, match="frames"):
        quarry.track_video(str(empty))
    cv2.imwrite(str(tmp_path / "000021.png"), frames[0][:50])
    with pytest.raises(ValueError, match="same size"):
        quarry.track_video(tmp_path)
