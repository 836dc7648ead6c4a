//! Vision bindings (quarry-vision): Gaussian blur, regional minima, watershed, and SIFT with
//! OpenCV-shaped outputs (keypoints as a structured array with `cv2.KeyPoint`'s fields,
//! descriptors `uint8 (N, 128)`, matches with `cv2.DMatch`'s fields).

use crate::args::{self, Checked, Values, data, map_err, value_error};
use numpy::{
    PyArray1, PyArray2, PyArrayDescr, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use quarry_core::{Keypoint, MinimumInfo, Plane};
use quarry_vision::matching::match_descriptors;
use quarry_vision::minima::Relief;
use quarry_vision::{
    BruteForceL2, Connectivity, MatchOptions, Minima, Sift as QSift, SiftParams, WatershedOptions,
    flood, gaussian_blur_f32, gaussian_blur_f64, regional_minima,
};

/// Reads a 2-D image `(H, W)` of `T` into a [`Plane`].
fn plane<T: Checked>(ob: &Bound<'_, PyAny>, name: &str) -> PyResult<Plane<T>> {
    let a = args::array::<T>(ob, name, "(H, W)", &[None, None], false, Values::Finite)?;
    let (h, w) = (a.shape()[0], a.shape()[1]);
    let (w32, h32) = (u32::try_from(w), u32::try_from(h));
    let (Ok(w32), Ok(h32)) = (w32, h32) else {
        return Err(value_error(name, "image is too large"));
    };
    Plane::from_vec(w32, h32, data(&a).to_vec()).map_err(|e| value_error(name, e))
}

/// A plane as a `(H, W)` numpy array.
fn plane_to_py<T: numpy::Element + Copy>(
    py: Python<'_>,
    p: Plane<T>,
) -> PyResult<Bound<'_, PyArray2<T>>> {
    let (w, h) = (p.width as usize, p.height as usize);
    PyArray1::from_vec(py, p.data).reshape([h, w])
}

/// Whether `ob` is a numpy array of dtype `T`.
fn is_dtype<T: numpy::Element>(ob: &Bound<'_, PyAny>) -> bool {
    ob.cast::<PyUntypedArray>()
        .is_ok_and(|a| a.dtype().is_equiv_to(&numpy::dtype::<T>(ob.py())))
}

/// Gaussian blur with OpenCV's kernel size rule and reflect-101 border, as
/// `cv2.GaussianBlur(img, (0, 0), sigma, borderType=cv2.BORDER_REFLECT_101)`.
///
/// `img` `(H, W)` float32 (sums in float32, as OpenCV's `CV_32F`) or float64; returns the same
/// dtype.
#[pyfunction]
#[pyo3(signature = (img, sigma))]
pub fn gaussian_blur<'py>(
    py: Python<'py>,
    img: &Bound<'py, PyAny>,
    sigma: f64,
) -> PyResult<Bound<'py, PyAny>> {
    if is_dtype::<f32>(img) {
        let p = plane::<f32>(img, "img")?;
        let out = py
            .detach(|| gaussian_blur_f32(&p, sigma))
            .map_err(map_err("gaussian_blur"))?;
        Ok(plane_to_py(py, out)?.into_any())
    } else if is_dtype::<f64>(img) {
        let p = plane::<f64>(img, "img")?;
        let out = py
            .detach(|| gaussian_blur_f64(&p, sigma))
            .map_err(map_err("gaussian_blur"))?;
        Ok(plane_to_py(py, out)?.into_any())
    } else {
        Err(dtype_error(img, "img", "float32 or float64"))
    }
}

/// The `TypeError` for an argument that is not an array of one of the `allowed` dtypes.
fn dtype_error(ob: &Bound<'_, PyAny>, name: &str, allowed: &str) -> PyErr {
    let got = ob.cast::<PyUntypedArray>().map_or_else(
        |_| {
            ob.get_type()
                .name()
                .map_or_else(|_| "?".to_string(), |n| n.to_string())
        },
        |a| format!("dtype {}", a.dtype()),
    );
    PyTypeError::new_err(format!(
        "{name}: expected a numpy.ndarray of {allowed}, got {got}"
    ))
}

fn connectivity(c: u8) -> PyResult<Connectivity> {
    match c {
        4 => Ok(Connectivity::Four),
        8 => Ok(Connectivity::Eight),
        other => Err(value_error(
            "connectivity",
            format!("{other} is not 4 or 8"),
        )),
    }
}

/// Labels `u32` -> int32 array (label counts are far below 2³¹ for any image that fits).
fn labels_to_py<'py>(py: Python<'py>, p: &Plane<u32>) -> PyResult<Bound<'py, PyArray2<i32>>> {
    plane_to_py(py, p.map(|&l| i32::try_from(l).unwrap_or(i32::MAX)))
}

/// Runs `$f::<T>` on the relief for its dtype (float32, float64, uint8).
macro_rules! by_relief {
    ($ob:expr, $name:expr, |$p:ident| $body:expr) => {
        if is_dtype::<f32>($ob) {
            let $p = plane::<f32>($ob, $name)?;
            $body
        } else if is_dtype::<u8>($ob) {
            let $p = plane::<u8>($ob, $name)?;
            $body
        } else if is_dtype::<f64>($ob) {
            let $p = plane::<f64>($ob, $name)?;
            $body
        } else {
            return Err(dtype_error($ob, $name, "float32, float64 or uint8"));
        }
    };
}

/// Regional minima (plateau-aware): `(labels, n)`, `labels` int32 `(H, W)` with `k` on the
/// pixels of minimum `k` (1..n, numbered in raster order of their first pixel) and 0 elsewhere —
/// `scipy.ndimage.label(skimage.morphology.local_minima(relief, connectivity=1 or 2))`.
///
/// `relief` `(H, W)` float32, float64 or uint8; `connectivity` 4 or 8.
#[pyfunction(name = "regional_minima")]
#[pyo3(signature = (relief, connectivity = 4))]
pub fn py_regional_minima<'py>(
    py: Python<'py>,
    relief: &Bound<'py, PyAny>,
    connectivity: u8,
) -> PyResult<(Bound<'py, PyArray2<i32>>, usize)> {
    let conn = self::connectivity(connectivity)?;
    let m = by_relief!(relief, "relief", |p| py
        .detach(|| regional_minima(&p, conn))
        .map_err(map_err("regional_minima"))?);
    let n = m.len();
    Ok((labels_to_py(py, &m.labels)?, n))
}

/// Seeds from a marker image: its distinct positive labels, compacted to 1..=K in increasing
/// order (so any int32 labels work without a label-sized allocation), with a record per seed;
/// returns the seeds and the original label of each compact one.
fn seeds_from_markers<T: Relief>(
    relief: &Plane<T>,
    markers: &[i32],
) -> PyResult<(Minima, Vec<i32>)> {
    if let Some((i, l)) = markers.iter().enumerate().find(|(_, l)| **l < 0) {
        return Err(value_error(
            "markers",
            format!("label {l} at flat index {i} is negative"),
        ));
    }
    let mut labels: Vec<i32> = markers.iter().copied().filter(|&l| l > 0).collect();
    labels.sort_unstable();
    labels.dedup();
    if labels.is_empty() {
        return Err(value_error("markers", "has no seed (every label is 0)"));
    }
    let compact = |l: i32| -> u32 {
        // labels holds l (it came from markers); the index fits u32 (< number of pixels)
        labels
            .binary_search(&l)
            .map_or(0, |k| u32::try_from(k + 1).unwrap_or(0))
    };
    let mut minima: Vec<MinimumInfo> = (1..=labels.len())
        .map(|id| MinimumInfo {
            id: u32::try_from(id).unwrap_or(u32::MAX),
            representative: (0, 0),
            size: 0,
            value: f64::NAN,
        })
        .collect();
    let w = relief.width as usize;
    let mut data = Vec::with_capacity(markers.len());
    for (i, &l) in markers.iter().enumerate() {
        let c = if l > 0 { compact(l) } else { 0 };
        data.push(c);
        if c > 0 {
            let m = &mut minima[c as usize - 1];
            if m.size == 0 {
                #[allow(clippy::cast_possible_truncation)]
                {
                    m.representative = ((i % w) as u32, (i / w) as u32);
                }
                m.value = relief.data[i].to_f64();
            }
            m.size += 1;
        }
    }
    let seeds = Minima {
        labels: Plane {
            width: relief.width,
            height: relief.height,
            data,
        },
        minima,
    };
    Ok((seeds, labels))
}

/// Meyer (priority-flood) watershed without lines: every pixel gets a label.
///
/// `relief` `(H, W)` float32, float64 or uint8. `markers`: optional int32 `(H, W)` seed labels
/// (0 = no seed, as `skimage.segmentation.watershed(relief, markers)`); without it every
/// regional minimum is a seed (labels as `regional_minima`). `connectivity` 4 (skimage's
/// default) or 8. Returns int32 labels `(H, W)`.
#[pyfunction]
#[pyo3(signature = (relief, markers = None, connectivity = 4))]
pub fn watershed<'py>(
    py: Python<'py>,
    relief: &Bound<'py, PyAny>,
    markers: Option<&Bound<'py, PyAny>>,
    connectivity: u8,
) -> PyResult<Bound<'py, PyArray2<i32>>> {
    let opts = WatershedOptions {
        connectivity: self::connectivity(connectivity)?,
    };
    let markers = markers.filter(|m| !m.is_none());
    let mut relabel: Option<Vec<i32>> = None;
    let seg = by_relief!(relief, "relief", |p| {
        match markers {
            Some(mk) => {
                let shape = format!("({}, {})", p.height, p.width);
                let dims = [Some(p.height as usize), Some(p.width as usize)];
                let a = args::array::<i32>(mk, "markers", &shape, &dims, false, Values::Finite)?;
                let (seeds, original) = seeds_from_markers(&p, data(&a))?;
                relabel = Some(original);
                py.detach(|| flood(&p, &seeds, opts))
            }
            None => py.detach(|| quarry_vision::watershed(&p, opts)),
        }
        .map_err(map_err("watershed"))?
    });
    match relabel {
        // back to the caller's marker labels
        Some(orig) => plane_to_py(
            py,
            seg.labels
                .map(|&c| orig.get((c as usize).wrapping_sub(1)).copied().unwrap_or(0)),
        ),
        None => labels_to_py(py, &seg.labels),
    }
}

/// numpy's dtype for keypoints, with `cv2.KeyPoint`'s fields.
const KEYPOINT_FIELDS: &str = "[('pt', '<f4', (2,)), ('size', '<f4'), ('angle', '<f4'), \
    ('response', '<f4'), ('octave', '<i4'), ('class_id', '<i4')]";
/// Bytes per keypoint record.
const KEYPOINT_BYTES: usize = 28;
/// numpy's dtype for matches, with `cv2.DMatch`'s fields.
const DMATCH_FIELDS: &str =
    "[('queryIdx', '<i4'), ('trainIdx', '<i4'), ('imgIdx', '<i4'), ('distance', '<f4')]";

/// A numpy structured dtype from its field list.
fn dtype<'py>(py: Python<'py>, fields: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = py.import("numpy")?;
    let spec = py.eval(&std::ffi::CString::new(fields)?, None, None)?;
    np.getattr("dtype")?.call1((spec,))
}

/// A structured array from packed little-endian records.
fn records<'py>(py: Python<'py>, bytes: &[u8], fields: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = py.import("numpy")?;
    np.getattr("frombuffer")?
        .call1((PyBytes::new(py, bytes), dtype(py, fields)?))?
        .call_method0("copy")
}

/// OpenCV's packed `KeyPoint.octave`: octave in the low byte (255 = −1), layer in the next,
/// `round((layer_offset + 0.5) · 255)` above.
fn pack_octave(k: &Keypoint) -> i32 {
    #[allow(clippy::cast_possible_truncation)]
    let xi = ((k.layer_offset + 0.5) * 255.0).round() as i32;
    (k.octave & 255) | ((k.layer & 255) << 8) | ((xi & 255) << 16)
}

fn keypoints_to_py<'py>(py: Python<'py>, kps: &[Keypoint]) -> PyResult<Bound<'py, PyAny>> {
    let mut b = Vec::with_capacity(kps.len() * KEYPOINT_BYTES);
    for k in kps {
        for v in [k.x, k.y, k.size(), k.angle_deg, k.response] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&pack_octave(k).to_le_bytes());
        b.extend_from_slice(&(-1i32).to_le_bytes());
    }
    records(py, &b, KEYPOINT_FIELDS)
}

/// Reads a keypoint structured array (as returned by `Sift.detect`, or built from OpenCV's
/// keypoints with the same fields) back into quarry keypoints.
fn keypoints_from_py(ob: &Bound<'_, PyAny>) -> PyResult<Vec<Keypoint>> {
    let py = ob.py();
    let arr = ob.cast::<PyUntypedArray>().map_err(|_| {
        PyTypeError::new_err("keypoints: expected the structured numpy array of Sift.detect")
    })?;
    let want = dtype(py, KEYPOINT_FIELDS)?;
    let want = want.cast::<PyArrayDescr>()?;
    if !arr.dtype().is_equiv_to(want) {
        return Err(PyTypeError::new_err(format!(
            "keypoints: expected dtype {KEYPOINT_FIELDS}, got {}",
            arr.dtype()
        )));
    }
    if arr.ndim() != 1 {
        return Err(value_error(
            "keypoints",
            format!("expected shape (N,), got {}", args::fmt_shape(arr.shape())),
        ));
    }
    if !arr.is_c_contiguous() {
        return Err(value_error(
            "keypoints",
            "array is not C-contiguous (pass np.ascontiguousarray(...))",
        ));
    }
    let bytes: Vec<u8> = arr.call_method0("tobytes")?.extract()?;
    let f32_at = |r: &[u8], o: usize| f32::from_le_bytes([r[o], r[o + 1], r[o + 2], r[o + 3]]);
    bytes
        .chunks_exact(KEYPOINT_BYTES)
        .enumerate()
        .map(|(i, r)| {
            let packed = i32::from_le_bytes([r[20], r[21], r[22], r[23]]);
            let octave = i32::from(((packed & 255) as u8).cast_signed());
            let layer = (packed >> 8) & 255;
            #[allow(clippy::cast_precision_loss)]
            let layer_offset = ((packed >> 16) & 255) as f32 / 255.0 - 0.5;
            let k = Keypoint {
                x: f32_at(r, 0),
                y: f32_at(r, 4),
                sigma: f32_at(r, 8) / 2.0,
                angle_deg: f32_at(r, 12),
                response: f32_at(r, 16),
                octave,
                layer,
                layer_offset,
            };
            let finite = [k.x, k.y, k.sigma, k.angle_deg, k.response]
                .iter()
                .all(|v| v.is_finite());
            if !finite || k.sigma <= 0.0 {
                return Err(value_error(
                    "keypoints",
                    format!("record {i} has a non-finite field or a size <= 0"),
                ));
            }
            Ok(k)
        })
        .collect()
}

fn descriptors_to_py<'py>(py: Python<'py>, d: &[[u8; 128]]) -> PyResult<Bound<'py, PyArray2<u8>>> {
    let flat: Vec<u8> = d.iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([d.len(), 128])
}

fn descriptors_from_py(ob: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<[u8; 128]>> {
    let a = args::array::<u8>(
        ob,
        name,
        "(N, 128)",
        &[None, Some(128)],
        true,
        Values::Finite,
    )?;
    Ok(data(&a)
        .chunks_exact(128)
        .map(|c| {
            let mut d = [0u8; 128];
            d.copy_from_slice(c);
            d
        })
        .collect())
}

/// SIFT (Lowe 2004) following OpenCV's `cv2.SIFT_create()` (defaults are OpenCV's).
///
/// Images are `uint8 (H, W)` grey images (at least 16 px a side). Keypoints come back as a
/// structured array with `cv2.KeyPoint`'s fields (`pt`, `size`, `angle`, `response`, `octave`
/// packed as OpenCV packs it, `class_id`), descriptors as `uint8 (N, 128)`.
#[pyclass(module = "quarry", frozen)]
pub struct Sift {
    inner: QSift,
}

#[pymethods]
impl Sift {
    /// `Sift(nfeatures=0, n_octave_layers=3, contrast_threshold=0.04, edge_threshold=10,
    /// sigma=1.6)`, as `cv2.SIFT_create`'s arguments.
    #[new]
    #[pyo3(signature = (nfeatures = 0, n_octave_layers = 3, contrast_threshold = 0.04, edge_threshold = 10.0, sigma = 1.6))]
    fn py_new(
        nfeatures: usize,
        n_octave_layers: u32,
        contrast_threshold: f64,
        edge_threshold: f64,
        sigma: f64,
    ) -> PyResult<Self> {
        let params = SiftParams {
            n_octave_layers,
            sigma,
            contrast_threshold,
            edge_threshold,
            max_features: nfeatures,
            ..SiftParams::default()
        };
        Ok(Self {
            inner: QSift::new(params).map_err(map_err("Sift"))?,
        })
    }

    /// Keypoints of `img`.
    fn detect<'py>(&self, py: Python<'py>, img: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let p = plane::<u8>(img, "img")?;
        let kps = py
            .detach(|| self.inner.detect_keypoints(&p))
            .map_err(map_err("Sift.detect"))?;
        keypoints_to_py(py, &kps)
    }

    /// Descriptors `uint8 (N, 128)` of `keypoints` in `img`.
    fn compute<'py>(
        &self,
        py: Python<'py>,
        img: &Bound<'py, PyAny>,
        keypoints: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<u8>>> {
        let p = plane::<u8>(img, "img")?;
        let kps = keypoints_from_py(keypoints)?;
        let d = py
            .detach(|| self.inner.describe(&p, &kps))
            .map_err(map_err("Sift.compute"))?;
        descriptors_to_py(py, &d)
    }

    /// `(keypoints, descriptors)` of `img`, building the scale space once.
    fn detect_and_compute<'py>(
        &self,
        py: Python<'py>,
        img: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyArray2<u8>>)> {
        let p = plane::<u8>(img, "img")?;
        let (kps, d) = py
            .detach(|| self.inner.extract(&p))
            .map_err(map_err("Sift.detect_and_compute"))?;
        Ok((keypoints_to_py(py, &kps)?, descriptors_to_py(py, &d)?))
    }
}

/// Brute-force L2 matching of SIFT descriptors (`query` and `train` `uint8 (N, 128)`), nearest
/// neighbour with Lowe's ratio test (`ratio`, None to disable), an optional `max_distance` and an
/// optional mutual check. Returns a structured array with `cv2.DMatch`'s fields (`queryIdx`,
/// `trainIdx`, `imgIdx` = 0, `distance`), sorted by query index.
#[pyfunction]
#[pyo3(signature = (query, train, ratio = Some(0.8), max_distance = None, mutual = false))]
pub fn match_sift<'py>(
    py: Python<'py>,
    query: &Bound<'py, PyAny>,
    train: &Bound<'py, PyAny>,
    ratio: Option<f32>,
    max_distance: Option<f32>,
    mutual: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let q = descriptors_from_py(query, "query")?;
    let t = descriptors_from_py(train, "train")?;
    let opts = MatchOptions {
        ratio,
        max_distance,
        mutual,
    };
    opts.validate().map_err(map_err("match_sift"))?;
    let m = py.detach(|| match_descriptors(&BruteForceL2, &q, &t, &opts));
    let mut b = Vec::with_capacity(m.len() * 16);
    for x in &m {
        for v in [x.query, x.train] {
            b.extend_from_slice(&i32::try_from(v).unwrap_or(i32::MAX).to_le_bytes());
        }
        b.extend_from_slice(&0i32.to_le_bytes());
        b.extend_from_slice(&x.distance.to_le_bytes());
    }
    records(py, &b, DMATCH_FIELDS)
}

/// Registers the vision functions and classes.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(gaussian_blur, m)?)?;
    m.add_function(wrap_pyfunction!(py_regional_minima, m)?)?;
    m.add_function(wrap_pyfunction!(watershed, m)?)?;
    m.add_function(wrap_pyfunction!(match_sift, m)?)?;
    m.add_class::<Sift>()?;
    Ok(())
}
