//! Image sequences as MOTChallenge lays them out (`img1/000001.jpg`, ...): the frames of a
//! directory in order, the input of `quarry motion` and the video trackers. Decoding is the
//! caller's (the reader pulls in no image codec).
//!
//! ```
//! let dir = std::env::temp_dir().join(format!("quarry-data-seq-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! for f in ["000002.jpg", "000001.jpg", "notes.txt"] {
//!     std::fs::write(dir.join(f), b"")?;
//! }
//! let frames = quarry_data::image_sequence::list_frames(&dir)?;
//! assert_eq!(frames.len(), 2);
//! assert!(frames[0].ends_with("000001.jpg"));
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::{Path, PathBuf};

use crate::{DataError, Result};

/// The PNG and JPEG files of `dir` (`.png`, `.jpg`, `.jpeg`, any case), sorted by name.
/// Errors: an unreadable directory, or one without such a file.
pub fn list_frames(dir: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir).map_err(|e| DataError::Io {
        path: dir.display().to_string(),
        reason: e.to_string(),
    })?;
    let mut files: Vec<PathBuf> = rd
        .filter_map(std::result::Result::ok)
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(DataError::Io {
            path: dir.display().to_string(),
            reason: "no PNG or JPEG frames".into(),
        });
    }
    Ok(files)
}
