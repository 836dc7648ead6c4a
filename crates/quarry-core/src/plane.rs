//! A dependency-free image plane.

use crate::CoreError;

/// A row-major image plane of `width` x `height` pixels of type `T` (u8 grey, f32 depth, f64
/// segmentation input, u32 labels, ...). Pixel `(x, y)` is `data[y * width + x]`.
///
/// ```
/// use quarry_core::Plane;
/// let mut p = Plane::new(3, 2, 0u8);
/// p.set(2, 1, 7);
/// assert_eq!(p.get(2, 1), Some(&7));
/// assert_eq!(p.get(3, 0), None);
/// assert!(Plane::from_vec(2, 2, vec![1u8; 3]).is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Plane<T> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Row-major pixels, `width * height` of them.
    pub data: Vec<T>,
}

impl<T: Clone> Plane<T> {
    /// A plane filled with `value`.
    pub fn new(width: u32, height: u32, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width as usize * height as usize],
        }
    }
}

impl<T> Plane<T> {
    /// A plane over existing row-major data; the length must be `width * height`.
    pub fn from_vec(width: u32, height: u32, data: Vec<T>) -> Result<Self, CoreError> {
        let expected = width as usize * height as usize;
        if data.len() != expected {
            return Err(CoreError::DimensionMismatch {
                what: "plane data length (width * height)",
                expected,
                got: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A plane whose pixel `(x, y)` is `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> T) -> Self {
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True when the plane has no pixels.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// `(width, height)`.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The linear index of pixel `(x, y)`, or `None` outside the plane.
    #[inline]
    pub fn index(&self, x: u32, y: u32) -> Option<usize> {
        (x < self.width && y < self.height).then(|| y as usize * self.width as usize + x as usize)
    }

    /// Pixel `(x, y)`, or `None` outside the plane.
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Option<&T> {
        self.index(x, y).map(|i| &self.data[i])
    }

    /// Mutable pixel `(x, y)`, or `None` outside the plane.
    #[inline]
    pub fn get_mut(&mut self, x: u32, y: u32) -> Option<&mut T> {
        self.index(x, y).map(move |i| &mut self.data[i])
    }

    /// Sets pixel `(x, y)`; returns false (and does nothing) outside the plane.
    #[inline]
    pub fn set(&mut self, x: u32, y: u32, v: T) -> bool {
        match self.index(x, y) {
            Some(i) => {
                self.data[i] = v;
                true
            }
            None => false,
        }
    }

    /// Row `y` as a slice (empty outside the plane).
    pub fn row(&self, y: u32) -> &[T] {
        if y >= self.height {
            return &[];
        }
        let w = self.width as usize;
        &self.data[y as usize * w..(y as usize + 1) * w]
    }

    /// A new plane with `f` applied to every pixel.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Plane<U> {
        Plane {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }

    /// Returns [`CoreError::Empty`] for a plane with no pixels.
    pub fn ensure_non_empty(&self, what: &'static str) -> Result<(), CoreError> {
        if self.width == 0 || self.height == 0 {
            Err(CoreError::Empty { what })
        } else {
            Ok(())
        }
    }
}

impl Plane<f32> {
    /// Returns [`CoreError::NonFinite`] if any pixel is NaN or infinite.
    pub fn ensure_finite(&self, what: &'static str) -> Result<(), CoreError> {
        if self.data.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(CoreError::NonFinite { what })
        }
    }
}

impl Plane<f64> {
    /// Returns [`CoreError::NonFinite`] if any pixel is NaN or infinite.
    pub fn ensure_finite(&self, what: &'static str) -> Result<(), CoreError> {
        if self.data.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(CoreError::NonFinite { what })
        }
    }
}

#[cfg(feature = "image")]
mod image_conv {
    use super::Plane;
    use image::{GrayImage, ImageBuffer, Luma};

    impl From<GrayImage> for Plane<u8> {
        fn from(img: GrayImage) -> Self {
            let (w, h) = img.dimensions();
            Plane {
                width: w,
                height: h,
                data: img.into_raw(),
            }
        }
    }

    impl From<&GrayImage> for Plane<u8> {
        fn from(img: &GrayImage) -> Self {
            let (w, h) = img.dimensions();
            Plane {
                width: w,
                height: h,
                data: img.as_raw().clone(),
            }
        }
    }

    impl From<Plane<u8>> for GrayImage {
        fn from(p: Plane<u8>) -> Self {
            // The length invariant of Plane guarantees the buffer fits.
            ImageBuffer::from_raw(p.width, p.height, p.data).unwrap_or_else(|| GrayImage::new(0, 0))
        }
    }

    impl From<ImageBuffer<Luma<f32>, Vec<f32>>> for Plane<f32> {
        fn from(img: ImageBuffer<Luma<f32>, Vec<f32>>) -> Self {
            let (w, h) = img.dimensions();
            Plane {
                width: w,
                height: h,
                data: img.into_raw(),
            }
        }
    }

    impl From<Plane<f32>> for ImageBuffer<Luma<f32>, Vec<f32>> {
        fn from(p: Plane<f32>) -> Self {
            ImageBuffer::from_raw(p.width, p.height, p.data)
                .unwrap_or_else(|| ImageBuffer::new(0, 0))
        }
    }

    impl From<ImageBuffer<Luma<u16>, Vec<u16>>> for Plane<u16> {
        fn from(img: ImageBuffer<Luma<u16>, Vec<u16>>) -> Self {
            let (w, h) = img.dimensions();
            Plane {
                width: w,
                height: h,
                data: img.into_raw(),
            }
        }
    }
}
