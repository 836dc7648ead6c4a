"""quarry's vision bindings against OpenCV (blur, SIFT keypoints, descriptors and matching) and
scikit-image (regional minima, watershed) on bench-data images."""
import cv2
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import ndimage
from skimage.morphology import local_minima
from skimage.segmentation import watershed as sk_watershed

import quarry

cv2.setNumThreads(1)


@pytest.fixture(scope="module")
def gray(bench_data):
    return cv2.imread(str(bench_data / "photo_gray.png"), cv2.IMREAD_GRAYSCALE)


@pytest.fixture(scope="module")
def blurred(gray):
    return cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 8.0, borderType=cv2.BORDER_REFLECT_101)


# ---------------------------------------------------------------- blur
def test_blur_matches_opencv(gray):
    # measured: f32 within 7.7e-5 (1 ulp at 255), f64 within 2e-13
    for dtype, tol in ((np.float32, 2e-4), (np.float64, 1e-12)):
        img = gray.astype(dtype)
        for sigma in (0.8, 2.0, 8.0):
            ours = quarry.gaussian_blur(img, sigma)
            ref = cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT_101)
            assert ours.dtype == dtype and ours.shape == img.shape
            np.testing.assert_allclose(ours, ref, rtol=0, atol=tol)


# ---------------------------------------------------------------- minima and watershed vs skimage
@pytest.mark.parametrize("conn", [4, 8])
def test_regional_minima_match_skimage(blurred, conn):
    labels, n = quarry.regional_minima(blurred, connectivity=conn)
    mask = local_minima(blurred, connectivity=1 if conn == 4 else 2)
    structure = ndimage.generate_binary_structure(2, 1 if conn == 4 else 2)
    ref, n_ref = ndimage.label(mask, structure=structure)
    assert n == n_ref and n > 50
    np.testing.assert_array_equal(labels, ref)


def test_watershed_matches_skimage(blurred):
    mask = local_minima(blurred, connectivity=1)
    markers, n = ndimage.label(mask)
    markers = markers.astype(np.int32)
    ref = sk_watershed(blurred, markers)
    ours = quarry.watershed(blurred, markers)
    print(f"watershed vs skimage on photo_gray (sigma 8, {n} seeds): {np.sum(ours != ref)} pixels differ")
    assert ours.dtype == np.int32 and n == 160
    np.testing.assert_array_equal(ours, ref)
    # seeds from the regional minima themselves give the same labels
    np.testing.assert_array_equal(quarry.watershed(blurred), ours)


@settings(max_examples=40, deadline=None)
@given(st.integers(4, 24), st.integers(4, 24), st.integers(0, 2**32 - 1))
def test_watershed_matches_skimage_on_random_reliefs(h, w, seed):
    """Random smooth reliefs without ties: the labels are those of skimage's watershed."""
    rng = np.random.default_rng(seed)
    relief = ndimage.gaussian_filter(rng.normal(size=(h, w)), 1.5) + rng.uniform(0, 1e-6, (h, w))
    mask = local_minima(relief, connectivity=1)
    markers, _ = ndimage.label(mask)
    np.testing.assert_array_equal(quarry.watershed(relief, markers.astype(np.int32)),
                                  sk_watershed(relief, markers))


# ---------------------------------------------------------------- SIFT vs OpenCV
def cv_keypoints_to_quarry(kps):
    dt = np.dtype([("pt", "<f4", (2,)), ("size", "<f4"), ("angle", "<f4"), ("response", "<f4"),
                   ("octave", "<i4"), ("class_id", "<i4")])
    a = np.zeros(len(kps), dt)
    for i, k in enumerate(kps):
        a[i] = (k.pt, k.size, k.angle, k.response, k.octave, k.class_id)
    return a


def test_sift_keypoints_and_descriptors_match_opencv(gray):
    kq, dq = quarry.Sift().detect_and_compute(gray)
    kc, dc = cv2.SIFT_create().detectAndCompute(gray, None)
    print(f"SIFT keypoints on photo_gray: quarry {len(kq)}, OpenCV {len(kc)}")
    assert dq.dtype == np.uint8 and dq.shape == (len(kq), 128)
    assert abs(len(kq) - len(kc)) <= 0.01 * len(kc)
    # the same keypoints: each OpenCV keypoint has a quarry one at the same place and size
    pc = np.array([k.pt for k in kc])
    sc = np.array([k.size for k in kc])
    d = np.linalg.norm(kq["pt"][None, :, :] - pc[:, None, :], axis=2)
    nearest = d.argmin(axis=1)
    same = (d.min(axis=1) < 0.01) & (np.abs(kq["size"][nearest] - sc) < 0.01)
    assert same.mean() > 0.97
    # quarry describes OpenCV's own keypoints like OpenCV does
    dqc = quarry.Sift().compute(gray, cv_keypoints_to_quarry(kc))
    dist = np.linalg.norm(dqc.astype(float) - dc.astype(float), axis=1)
    print(f"descriptors of OpenCV's keypoints: {np.mean(dist == 0):.4f} identical, "
          f"{np.mean(dist < 10):.4f} within L2 10 (norm ~512)")
    assert np.mean(dist == 0) > 0.99
    # packed octave round-trips: OpenCV unpacks quarry's keypoints to the same descriptors
    kq_cv = [cv2.KeyPoint(float(k["pt"][0]), float(k["pt"][1]), float(k["size"]), float(k["angle"]),
                          float(k["response"]), int(k["octave"]), -1) for k in kq]
    _, dcq = cv2.SIFT_create().compute(gray, kq_cv)
    assert np.mean(np.linalg.norm(dcq.astype(float) - dq.astype(float), axis=1) < 10) > 0.97


def proj(H, p):
    q = np.c_[p, np.ones(len(p))] @ H.T
    return q[:, :2] / q[:, 2:3]


def inside(p, shape):
    h, w = shape
    return (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)


def matching_score(p1, p2, matches, H, shape1, shape2):
    """peers/bench_sift.py's matching score: correct ratio-test matches / keypoints in view."""
    q = proj(H, p1[matches["queryIdx"]]) if len(matches) else np.zeros((0, 2))
    correct = int(np.sum(np.linalg.norm(q - p2[matches["trainIdx"]], axis=1) < 3.0))
    n1 = int(np.sum(inside(proj(H, p1), shape2)))
    n2 = int(np.sum(inside(proj(np.linalg.inv(H), p2), shape1)))
    return correct / min(n1, n2)


@pytest.mark.parametrize("name", ["rot30_s0.8", "blur2", "bright40"])
def test_sift_matching_matches_opencv(bench_data, gray, name):
    g2 = cv2.imread(str(bench_data / f"sift_{name}.png"), cv2.IMREAD_GRAYSCALE)
    H = np.loadtxt(bench_data / f"sift_{name}_H.csv", delimiter=",")
    s = quarry.Sift()
    k1, d1 = s.detect_and_compute(gray)
    k2, d2 = s.detect_and_compute(g2)
    ours = quarry.match_sift(d1, d2, ratio=0.8)
    # OpenCV's BFMatcher on the same descriptors finds the same matches
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance]
    assert [(m.queryIdx, m.trainIdx) for m in good] == list(zip(ours["queryIdx"], ours["trainIdx"]))
    np.testing.assert_allclose(ours["distance"], [m.distance for m in good], rtol=1e-5)
    # and the whole pipeline scores like OpenCV's (bench_sift.py protocol)
    sc = cv2.SIFT_create()
    c1, e1 = sc.detectAndCompute(gray, None)
    c2, e2 = sc.detectAndCompute(g2, None)
    knn = cv2.BFMatcher(cv2.NORM_L2).knnMatch(e1, e2, k=2)
    cgood = np.array([(m[0].queryIdx, m[0].trainIdx) for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance],
                     dtype=[("queryIdx", "<i4"), ("trainIdx", "<i4")])
    ms_q = matching_score(k1["pt"], k2["pt"], ours, H, gray.shape, g2.shape)
    ms_c = matching_score(np.array([k.pt for k in c1]), np.array([k.pt for k in c2]), cgood, H, gray.shape, g2.shape)
    print(f"matching score photo_gray -> {name}: quarry {ms_q:.4f}, OpenCV {ms_c:.4f}")
    assert ms_q >= ms_c - 0.03 and ms_q > 0.4


def test_vision_errors_name_the_argument(gray):
    with pytest.raises(TypeError, match="img"):
        quarry.Sift().detect(gray.astype(np.float32))
    with pytest.raises(ValueError, match="img"):
        quarry.Sift().detect(gray[:, ::2])
    with pytest.raises(ValueError, match="img"):
        quarry.Sift().detect(np.zeros((0, 5), np.uint8))
    with pytest.raises(ValueError, match="SIFT"):
        quarry.Sift().detect(np.zeros((8, 8), np.uint8))
    with pytest.raises(ValueError, match="img"):
        quarry.gaussian_blur(np.array([[np.nan, 0.0]]), 1.0)
    with pytest.raises(ValueError, match="sigma"):
        quarry.gaussian_blur(np.zeros((4, 4)), -1.0)
    with pytest.raises(ValueError, match="relief"):
        quarry.watershed(np.zeros(5))
    with pytest.raises(ValueError, match="markers"):
        quarry.watershed(np.zeros((4, 4)), np.zeros((4, 5), np.int32))
    with pytest.raises(ValueError, match="markers"):
        quarry.watershed(np.zeros((4, 4)), np.zeros((4, 4), np.int32))
    with pytest.raises(TypeError, match="markers"):
        quarry.watershed(np.zeros((4, 4)), np.zeros((4, 4), np.int64))
    with pytest.raises(ValueError, match="connectivity"):
        quarry.regional_minima(np.zeros((4, 4)), connectivity=6)
    with pytest.raises(TypeError, match="keypoints"):
        quarry.Sift().compute(gray, np.zeros((3, 7), np.float32))
    with pytest.raises(ValueError, match="train"):
        quarry.match_sift(np.zeros((2, 128), np.uint8), np.zeros((2, 64), np.uint8))
    with pytest.raises(ValueError, match="ratio"):
        quarry.match_sift(np.zeros((2, 128), np.uint8), np.zeros((2, 128), np.uint8), ratio=1.5)


def test_watershed_keeps_arbitrary_marker_labels(blurred):
    """Marker labels need not be 1..K: any positive int32 labels come back as they were (and a
    label of 2**31 - 1 allocates nothing label-sized)."""
    markers, n = ndimage.label(local_minima(blurred, connectivity=1))
    markers = markers.astype(np.int32)
    ref = quarry.watershed(blurred, markers)
    sparse = np.where(markers > 0, markers * 1000 + 7, 0).astype(np.int32)
    sparse[sparse == sparse.max()] = 2**31 - 1
    out = quarry.watershed(blurred, sparse)
    lut = {int(m): int(s) for m, s in zip(markers[markers > 0], sparse[markers > 0])}
    np.testing.assert_array_equal(out, np.vectorize(lut.get)(ref))
    np.testing.assert_array_equal(out, sk_watershed(blurred, sparse))
