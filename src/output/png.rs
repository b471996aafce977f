//! Grey + alpha PNG encoding with the deflate work split across threads.
//!
//! The mask textures are noise and deflate slowly at the highest level: a 256² mask took longer
//! than any other part of pack on a many-core machine. The image is cut into bands of
//! [`BAND_ROWS`] rows; each band is filtered and deflated on its own (a compressor per band, the
//! band ended by a sync flush, the last one by the final block) and the bands are joined into one
//! zlib stream, as pigz does. The bands are fixed by the image's height, not by the threads, so
//! the bytes are the same on any machine. A band's matches cannot reach into the band before it:
//! on the Stanford dragon's four masks (256² and its mips) that costs 982 bytes of 100 669 (1 %)
//! with bands of 128 rows, 4.7 kB with bands of 32. So the 256² mask deflates in two halves side
//! by side, taking half the time, and larger masks in more.
//!
//! Each row takes the filter whose output has the smallest sum of absolute values (read as
//! signed bytes), the usual adaptive heuristic.

use flate2::{Compress, Compression, FlushCompress, Status};
use rayon::prelude::*;

/// Rows per independently deflated band (64 KiB of filtered bytes at a width of 256).
pub const BAND_ROWS: usize = 128;

/// `pixels` (grey, alpha interleaved, row-major, `width × height`) as a PNG.
pub fn grey_alpha_png(pixels: &[u8], width: u32, height: u32) -> Vec<u8> {
    let stride = 2 * width as usize;
    assert_eq!(pixels.len(), stride * height as usize);
    let rows: Vec<&[u8]> = pixels.chunks_exact(stride.max(1)).collect();
    let bands: Vec<(Vec<u8>, Vec<u8>)> = (0..rows.len())
        .step_by(BAND_ROWS)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|start| {
            let end = (start + BAND_ROWS).min(rows.len());
            let mut raw = Vec::with_capacity((end - start) * (stride + 1));
            for y in start..end {
                filter_row(y.checked_sub(1).map(|p| rows[p]), rows[y], &mut raw);
            }
            let deflated = deflate(&raw, end == rows.len());
            (raw, deflated)
        })
        .collect();
    let mut zlib = vec![0x78, 0xda];
    let mut adler = Adler32::default();
    for (raw, deflated) in &bands {
        adler.update(raw);
        zlib.extend_from_slice(deflated);
    }
    if bands.is_empty() {
        zlib.extend_from_slice(&deflate(&[], true));
    }
    zlib.extend_from_slice(&adler.value().to_be_bytes());

    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut header = Vec::with_capacity(13);
    header.extend_from_slice(&width.to_be_bytes());
    header.extend_from_slice(&height.to_be_bytes());
    header.extend_from_slice(&[8, 4, 0, 0, 0]); // 8 bits, grey + alpha, deflate, adaptive, none
    chunk(&mut png, b"IHDR", &header);
    chunk(&mut png, b"IDAT", &zlib);
    chunk(&mut png, b"IEND", &[]);
    png
}

/// Appends `row` filtered against `prev` (the row above; none for the first), its filter byte
/// first, choosing the filter by the smallest sum of absolute signed values.
fn filter_row(prev: Option<&[u8]>, row: &[u8], out: &mut Vec<u8>) {
    const BPP: usize = 2;
    let up = |i: usize| prev.map_or(0, |p| p[i]);
    let left = |i: usize| if i >= BPP { row[i - BPP] } else { 0 };
    let up_left = |i: usize| if i >= BPP { up(i - BPP) } else { 0 };
    let predict = |filter: u8, i: usize| -> u8 {
        match filter {
            0 => 0,
            1 => left(i),
            2 => up(i),
            3 => ((left(i) as u16 + up(i) as u16) / 2) as u8,
            _ => paeth(left(i), up(i), up_left(i)),
        }
    };
    let cost = |filter: u8| -> u64 {
        (0..row.len())
            .map(|i| (row[i].wrapping_sub(predict(filter, i)) as i8).unsigned_abs() as u64)
            .sum()
    };
    let filter = (0..5u8).min_by_key(|&f| cost(f)).unwrap_or(0);
    out.push(filter);
    out.extend((0..row.len()).map(|i| row[i].wrapping_sub(predict(filter, i))));
}

/// The Paeth predictor of the PNG specification.
fn paeth(a: u8, b: u8, c: u8) -> u8 {
    let p = a as i16 + b as i16 - c as i16;
    let (pa, pb, pc) = (
        (p - a as i16).abs(),
        (p - b as i16).abs(),
        (p - c as i16).abs(),
    );
    if pa <= pb && pa <= pc {
        a
    } else if pb <= pc {
        b
    } else {
        c
    }
}

/// `raw` deflated at the highest level as raw deflate blocks: ended by a sync flush (byte
/// aligned, not final) or, for the `last` band, by the final block.
fn deflate(raw: &[u8], last: bool) -> Vec<u8> {
    let mut c = Compress::new(Compression::best(), false);
    let flush = if last {
        FlushCompress::Finish
    } else {
        FlushCompress::Sync
    };
    let mut out = Vec::with_capacity(raw.len() + raw.len() / 64 + 64);
    loop {
        let at = c.total_in() as usize;
        let status = (c.compress_vec(&raw[at..], &mut out, flush))
            .expect("deflating into memory cannot fail");
        let flushed = c.total_in() as usize == raw.len() && out.len() < out.capacity();
        if status == Status::StreamEnd || (!last && flushed) {
            return out;
        }
        out.reserve(out.capacity().max(64));
    }
}

/// The Adler-32 checksum zlib ends with.
struct Adler32 {
    a: u32,
    b: u32,
}

impl Default for Adler32 {
    fn default() -> Adler32 {
        Adler32 { a: 1, b: 0 }
    }
}

impl Adler32 {
    fn update(&mut self, bytes: &[u8]) {
        const MOD: u32 = 65521;
        // 5552 bytes at most between reductions keep `b` within 32 bits
        for block in bytes.chunks(5552) {
            for &x in block {
                self.a += x as u32;
                self.b += self.a;
            }
            self.a %= MOD;
            self.b %= MOD;
        }
    }

    fn value(&self) -> u32 {
        (self.b << 16) | self.a
    }
}

/// Appends a PNG chunk: length, type, data, CRC of type and data.
fn chunk(png: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    png.extend_from_slice(&(data.len() as u32).to_be_bytes());
    png.extend_from_slice(kind);
    png.extend_from_slice(data);
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    png.extend_from_slice(&crc.finalize().to_be_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(n: usize, seed: u32) -> Vec<u8> {
        let mut x = seed;
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                (x >> 24) as u8
            })
            .collect()
    }

    #[test]
    fn bands_decode_to_the_pixels() {
        // several bands, the last one short; a smooth grey (filters help) and noisy alpha
        let (w, h) = (77u32, 3 * BAND_ROWS as u32 + 5);
        let alpha = noise((w * h) as usize, 7);
        let pixels: Vec<u8> = (0..(w * h) as usize)
            .flat_map(|i| [(i % w as usize) as u8, alpha[i]])
            .collect();
        let png = grey_alpha_png(&pixels, w, h);
        let img = image::load_from_memory(&png).unwrap().to_luma_alpha8();
        assert_eq!(img.dimensions(), (w, h));
        assert_eq!(img.into_raw(), pixels);
        assert_eq!(png, grey_alpha_png(&pixels, w, h));
    }

    #[test]
    fn adler_matches_the_reference_value() {
        let mut a = Adler32::default();
        a.update(b"Wikipedia");
        assert_eq!(a.value(), 0x11E6_0398);
        let mut long = Adler32::default();
        long.update(&vec![255u8; 100_000]);
        let mut split = Adler32::default();
        split.update(&vec![255u8; 40_000]);
        split.update(&vec![255u8; 60_000]);
        assert_eq!(long.value(), split.value());
    }
}
