//! Decompression with a bound on what comes out. Every compressed input the crate reads (an
//! archive's directories, metadata and tiles, a stored tile's codings, a zipped or gzipped
//! SRTM file) says little about the size it inflates to, and a few kilobytes of deflate can
//! stand for a gigabyte. Each reader therefore names the most its format allows, and reading
//! stops one byte past it, before that byte is kept.

use std::io::Read;

/// Why an input could not be decompressed.
#[derive(Debug, thiserror::Error)]
pub enum InflateError {
    #[error("it inflates to more than {limit} bytes, the most it may hold")]
    TooLarge { limit: u64 },
    #[error("it does not inflate: {0}")]
    Corrupt(#[from] std::io::Error),
}

/// Everything `reader` gives, as long as that is at most `limit` bytes.
pub fn read_at_most(reader: impl Read, limit: u64) -> Result<Vec<u8>, InflateError> {
    let mut out = Vec::new();
    reader.take(limit.saturating_add(1)).read_to_end(&mut out)?;
    if out.len() as u64 > limit {
        return Err(InflateError::TooLarge { limit });
    }
    Ok(out)
}

/// `bytes` gunzipped, at most `limit` bytes of it.
pub fn gunzip(bytes: &[u8], limit: u64) -> Result<Vec<u8>, InflateError> {
    read_at_most(flate2::read::GzDecoder::new(bytes), limit)
}

/// `bytes` decoded from brotli, at most `limit` bytes of it.
pub fn unbrotli(bytes: &[u8], limit: u64) -> Result<Vec<u8>, InflateError> {
    read_at_most(brotli::Decompressor::new(bytes, 1 << 16), limit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        encoder.write_all(data).unwrap();
        encoder.finish().unwrap()
    }

    #[test]
    fn an_input_within_its_limit_inflates_whole() {
        let data = vec![7u8; 1000];
        assert_eq!(gunzip(&gzip(&data), 1000).unwrap(), data);
    }

    #[test]
    fn an_input_past_its_limit_stops_one_byte_past_it() {
        // A megabyte of zeros is about a kilobyte of gzip.
        let bomb = gzip(&vec![0u8; 1 << 20]);
        assert!(bomb.len() < 2048);
        let error = gunzip(&bomb, 4096).unwrap_err();
        assert!(
            matches!(error, InflateError::TooLarge { limit: 4096 }),
            "{error}"
        );
        let mut counted = CountingReader::default();
        let _ = read_at_most(&mut counted, 10);
        assert_eq!(counted.given, 11);
    }

    #[test]
    fn a_damaged_input_is_corrupt_not_large() {
        let mut damaged = gzip(b"a tile");
        let at = damaged.len() - 12;
        damaged[at] ^= 0xff;
        assert!(matches!(
            gunzip(&damaged, 100),
            Err(InflateError::Corrupt(_))
        ));
        assert!(matches!(
            unbrotli(b"not brotli at all", 100),
            Err(InflateError::Corrupt(_))
        ));
    }

    /// An endless reader that counts the bytes taken from it.
    #[derive(Default)]
    struct CountingReader {
        given: usize,
    }

    impl Read for CountingReader {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            buf.fill(0);
            self.given += buf.len();
            Ok(buf.len())
        }
    }
}
