//! Princeton Tracking Benchmark (PTB) RGB-D sequences, the real-data input of
//! `quarry_trackers::rgbd_person` (`quarry rgbd --sequence DIR`).
//!
//! Layout: `DIR/rgb/*.png` and `DIR/depth/*.png`, paired by the last run of digits in the file
//! stem (`r-12345-7.png` is frame 7), the first box in `DIR/init.txt` (`x,y,w,h`, top-left,
//! pixels). Depth PNGs are 16-bit: PTB stores millimetres with a 3-bit circular shift
//! ([`DepthFormat::Ptb`]), other recordings plain millimetres ([`DepthFormat::Millimetres`]).
//!
//! This module lists and pairs the files and converts decoded depth values; decoding the PNGs
//! themselves is the caller's (quarry-cli uses the `image` crate), so the reader pulls in no
//! image codec.
//!
//! ```
//! use quarry_data::ptb::{DepthFormat, depth_metres, frame_number, parse_box};
//! assert_eq!(frame_number(std::path::Path::new("r-123_45.png")), Some(45));
//! let b = parse_box("10,20,30,40")?;
//! assert_eq!((b.w, b.h), (30.0, 40.0));
//! // 1500 mm stored with PTB's 3-bit shift
//! let raw = [1500u16.rotate_left(3)];
//! let d = depth_metres(&raw, 1, 1, DepthFormat::Ptb)?;
//! assert_eq!(d.data, vec![1.5]);
//! # Ok::<(), quarry_data::DataError>(())
//! ```

use std::path::{Path, PathBuf};

use quarry_core::{BBox, Plane};

use crate::{DataError, Result};

/// How a depth PNG stores its millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DepthFormat {
    /// PTB's encoding: millimetres rotated left by 3 bits (undone by a right rotation).
    #[default]
    Ptb,
    /// Plain millimetres.
    Millimetres,
}

impl DepthFormat {
    /// Parses `ptb` or `mm`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "ptb" => Ok(Self::Ptb),
            "mm" => Ok(Self::Millimetres),
            o => Err(DataError::Io {
                path: String::new(),
                reason: format!("depth format {o:?}: expected ptb or mm"),
            }),
        }
    }
}

/// One frame of a sequence: its number and its two files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PtbFrame {
    /// Frame number (the last run of digits of the RGB file stem).
    pub number: u64,
    /// The RGB PNG.
    pub rgb: PathBuf,
    /// The depth PNG with the same number.
    pub depth: PathBuf,
}

/// A PTB-layout sequence: its frames in number order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PtbSequence {
    /// The sequence directory.
    pub dir: PathBuf,
    /// Every RGB frame with its depth frame, by number.
    pub frames: Vec<PtbFrame>,
}

impl PtbSequence {
    /// Lists `dir/rgb` and `dir/depth` and pairs the frames by number. Errors: a missing or
    /// unreadable directory, no RGB frame, an RGB frame without a depth frame (named).
    pub fn open(dir: &Path) -> Result<Self> {
        let rgbs = list_numbered_pngs(&dir.join("rgb"))?;
        let depths = list_numbered_pngs(&dir.join("depth"))?;
        if rgbs.is_empty() {
            return Err(DataError::Io {
                path: dir.display().to_string(),
                reason: "no PNG frames in rgb/".into(),
            });
        }
        let frames = rgbs
            .into_iter()
            .map(|(number, rgb)| {
                let depth = depths
                    .binary_search_by_key(&number, |(m, _)| *m)
                    .map(|i| depths[i].1.clone())
                    .map_err(|_| DataError::Io {
                        path: rgb.display().to_string(),
                        reason: format!("frame {number} has no depth frame"),
                    })?;
                Ok(PtbFrame { number, rgb, depth })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            dir: dir.to_path_buf(),
            frames,
        })
    }

    /// The first box, from the first line of `init.txt`.
    pub fn init_box(&self) -> Result<BBox> {
        let p = self.dir.join("init.txt");
        let text = read_small(&p, 1 << 16)?;
        parse_box(text.lines().next().unwrap_or("")).map_err(|e| match e {
            DataError::Parse { reason, .. } => DataError::Parse {
                path: p.display().to_string(),
                line: 1,
                reason,
            },
            other => other,
        })
    }
}

/// Reads a text file of at most `max` bytes (an annotation, not a stream).
fn read_small(p: &Path, max: u64) -> Result<String> {
    let io = |e: std::io::Error| DataError::Io {
        path: p.display().to_string(),
        reason: e.to_string(),
    };
    let len = std::fs::metadata(p).map_err(io)?.len();
    if len > max {
        return Err(DataError::Io {
            path: p.display().to_string(),
            reason: format!("{len} bytes is too large (at most {max})"),
        });
    }
    std::fs::read_to_string(p).map_err(io)
}

/// Parses a box `x,y,w,h` (commas or white space; top-left corner, pixels; further values are
/// ignored). Errors: fewer than four numbers, a value that is not finite, `w` or `h` ≤ 0.
pub fn parse_box(s: &str) -> Result<BBox> {
    let bad = |reason: String| DataError::Parse {
        path: "box".into(),
        line: 1,
        reason,
    };
    let v: Vec<f64> = s
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .take(4)
        .map(str::parse)
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| bad(format!("box {s:?}: {e}")))?;
    if v.len() < 4 || !v.iter().all(|x| x.is_finite()) || v[2] <= 0.0 || v[3] <= 0.0 {
        return Err(bad(format!(
            "box {s:?}: need x,y,w,h with finite values and w, h > 0"
        )));
    }
    Ok(BBox::from_ltwh(v[0], v[1], v[2], v[3]))
}

/// The frame number of a file: the last run of digits in its stem.
pub fn frame_number(p: &Path) -> Option<u64> {
    let stem = p.file_stem()?.to_str()?;
    let mut last = None;
    let mut cur = String::new();
    for c in stem.chars().chain(std::iter::once('_')) {
        if c.is_ascii_digit() {
            cur.push(c);
        } else if !cur.is_empty() {
            last = cur.parse().ok();
            cur.clear();
        }
    }
    last
}

/// The PNG files of `dir` that carry a frame number, sorted by it.
pub fn list_numbered_pngs(dir: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let io = |e: std::io::Error| DataError::Io {
        path: dir.display().to_string(),
        reason: e.to_string(),
    };
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir).map_err(io)? {
        let p = e.map_err(io)?.path();
        if p.extension()
            .and_then(|x| x.to_str())
            .is_some_and(|x| x.eq_ignore_ascii_case("png"))
            && let Some(n) = frame_number(&p)
        {
            v.push((n, p));
        }
    }
    v.sort();
    Ok(v)
}

/// Decoded 16-bit depth values (`width × height`, row-major) in metres.
pub fn depth_metres(
    raw: &[u16],
    width: u32,
    height: u32,
    format: DepthFormat,
) -> Result<Plane<f32>> {
    let data = raw
        .iter()
        .map(|&v| {
            let mm = match format {
                DepthFormat::Ptb => v.rotate_right(3),
                DepthFormat::Millimetres => v,
            };
            f32::from(mm) / 1000.0
        })
        .collect();
    Ok(Plane::from_vec(width, height, data)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_boxes_and_depth() {
        assert_eq!(frame_number(Path::new("r-123_45.png")), Some(45));
        assert_eq!(frame_number(Path::new("abc.png")), None);
        assert!(parse_box("1,2,3,4").is_ok());
        assert!(parse_box("1 2 3 4 0.9").is_ok());
        assert!(parse_box("1,2,0,4").is_err());
        assert!(parse_box("1,2,nan,4").is_err());
        assert!(parse_box("1,2").is_err());
        assert!(parse_box("").is_err());
        let d = depth_metres(&[1000, 2000], 2, 1, DepthFormat::Millimetres).unwrap();
        assert_eq!(d.data, vec![1.0, 2.0]);
        assert!(depth_metres(&[1, 2, 3], 2, 1, DepthFormat::Ptb).is_err());
        assert_eq!(DepthFormat::parse("mm").unwrap(), DepthFormat::Millimetres);
        assert!(DepthFormat::parse("cm").is_err());
    }

    #[test]
    fn a_sequence_pairs_frames_and_names_a_missing_depth() {
        let root = std::env::temp_dir().join(format!("quarry-data-ptb-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(root.join("rgb")).unwrap();
        std::fs::create_dir_all(root.join("depth")).unwrap();
        for k in [2u32, 1, 10] {
            std::fs::write(root.join(format!("rgb/r-99-{k}.png")), b"").unwrap();
            std::fs::write(root.join(format!("depth/d-99-{k}.png")), b"").unwrap();
        }
        std::fs::write(root.join("init.txt"), "5,6,7,8\n").unwrap();
        let s = PtbSequence::open(&root).unwrap();
        let numbers: Vec<u64> = s.frames.iter().map(|f| f.number).collect();
        assert_eq!(numbers, vec![1, 2, 10]);
        assert_eq!(s.init_box().unwrap(), BBox::from_ltwh(5.0, 6.0, 7.0, 8.0));
        std::fs::write(root.join("rgb/r-99-11.png"), b"").unwrap();
        let e = PtbSequence::open(&root).unwrap_err();
        assert!(e.to_string().contains("frame 11 has no depth frame"), "{e}");
        std::fs::write(root.join("init.txt"), "x\n").unwrap();
        std::fs::remove_file(root.join("rgb/r-99-11.png")).unwrap();
        let s = PtbSequence::open(&root).unwrap();
        assert!(s.init_box().is_err());
        assert!(PtbSequence::open(&root.join("nope")).is_err());
        let _ = std::fs::remove_dir_all(&root);
    }
}
