//! Shared by the fuzz targets that read their input as numbers.

/// The input as little-endian `f64`s, 8 bytes each (a short last chunk is zero-padded): every
/// bit pattern, NaN and infinities included, is reachable.
pub fn floats(data: &[u8]) -> impl Iterator<Item = f64> + '_ {
    data.chunks(8).map(|c| {
        let mut b = [0u8; 8];
        b[..c.len()].copy_from_slice(c);
        f64::from_le_bytes(b)
    })
}
