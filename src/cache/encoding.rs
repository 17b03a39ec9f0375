//! Content codings: a tile is compressed once, when it is made, into every coding that makes it
//! smaller, and each request gets the best form its `Accept-Encoding` allows, without
//! compressing anything per request.

use std::io::Write;

use bytes::Bytes;

use crate::format::Encoding;

/// A compressed form is kept only when it is at most this share of the original.
const WORTH_KEEPING: f64 = 0.9;

/// Brotli quality and window: quality 5 compresses a 2 MB tile in tens of milliseconds, about
/// as small as gzip's best.
const BROTLI_QUALITY: u32 = 5;
const BROTLI_WINDOW: u32 = 22;

/// The gzip level of the forms kept. On Monaco's tiles (one core) level 4 takes 41–57 ms on a
/// 1.9–2.5 MB meshopt tile against 84–122 ms at the default level 6, 1.2–1.3 % larger, and
/// 189 ms on a 12.2 MB plain one against 265 ms, 0.4 % larger: a seed spends more time
/// compressing than rendering, and brotli, made beside it, is the smaller form anyway.
const GZIP_LEVEL: u32 = 4;

/// The levels of a form made while a client waits. On a 13.8 MB tile (one core): gzip level 1
/// takes 75–110 ms against 420–600 ms at the default level (9 % larger); brotli quality 0
/// 105 ms against 590–950 ms at quality 5 (41 % larger).
const QUICK_GZIP_LEVEL: u32 = 1;
const QUICK_BROTLI_QUALITY: u32 = 0;

/// One tile in each coding that pays.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Bodies {
    pub identity: Bytes,
    pub gzip: Option<Bytes>,
    pub brotli: Option<Bytes>,
    /// Made for a client waiting for it, with at most the one coded form named (none for
    /// identity) made at a fast level, until the forms kept replace it ([`Bodies::compress`]).
    pub quick: Option<Encoding>,
}

#[derive(Debug, thiserror::Error)]
pub enum CodingError {
    #[error("{coding} body cannot be decoded: {source}")]
    Corrupt {
        coding: &'static str,
        #[source]
        source: crate::inflate::InflateError,
    },
    #[error("compressing a tile failed: {0}")]
    Compress(#[source] std::io::Error),
    #[error("{coding} body does not match the tile's digest")]
    Mismatch { coding: &'static str },
}

impl Bodies {
    /// Compresses `identity` with gzip and brotli, keeping each form that is small enough to be
    /// worth sending. The two are made at once, on two threads: a tile made for a request is
    /// answered when both are ready, so it waits for the slower rather than for their sum.
    pub fn compress(identity: Vec<u8>) -> Result<Bodies, CodingError> {
        let keep = |form| worth_keeping(identity.len(), form);
        let (gzipped, brotlied) = std::thread::scope(|scope| {
            let gzipping = scope.spawn(|| gzip(&identity));
            let brotlied = brotli(&identity, BROTLI_QUALITY);
            let gzipped = gzipping
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (gzipped, brotlied)
        });
        let gzip = keep(gzipped.map_err(CodingError::Compress)?);
        let brotli = keep(brotlied.map_err(CodingError::Compress)?);
        Ok(Bodies {
            identity: Bytes::from(identity),
            gzip,
            brotli,
            quick: None,
        })
    }

    /// The form a client waits for, made fast: gzip when it accepts gzip (the smaller of the
    /// two at these levels, and about as quick), else brotli, else none.
    pub fn quick(identity: Vec<u8>, accepted: &Accepted) -> Result<Bodies, CodingError> {
        let keep = |form| worth_keeping(identity.len(), form);
        let mut bodies = Bodies {
            quick: Some(Encoding::Identity),
            ..Bodies::default()
        };
        if accepted.allows(Encoding::Gzip) {
            let made = gzip_at(&identity, QUICK_GZIP_LEVEL).map_err(CodingError::Compress)?;
            bodies.gzip = keep(made);
            bodies.quick = Some(Encoding::Gzip);
        } else if accepted.allows(Encoding::Brotli) {
            let made = brotli(&identity, QUICK_BROTLI_QUALITY).map_err(CodingError::Compress)?;
            bodies.brotli = keep(made);
            bodies.quick = Some(Encoding::Brotli);
        }
        bodies.identity = Bytes::from(identity);
        Ok(bodies)
    }

    /// Whether a client that accepts `accepted` should wait for the forms kept: these bodies
    /// were made in haste for another client, and would give this one the identity body
    /// though it accepts a coding not tried.
    pub fn awaits_better_for(&self, accepted: &Accepted) -> bool {
        let Some(tried) = self.quick else {
            return false;
        };
        self.choose(accepted).0 == Encoding::Identity
            && [Encoding::Gzip, Encoding::Brotli]
                .into_iter()
                .any(|coding| coding != tried && accepted.allows(coding))
    }

    /// Rebuilds the bodies from their stored forms: the primary body in its coding (gzip or
    /// identity) and the brotli form if any; the identity form is decoded once, here, and is
    /// damaged if it would be longer than `max_tile` bytes.
    pub fn from_stored(
        primary: Vec<u8>,
        coding: Encoding,
        brotli: Option<Vec<u8>>,
        max_tile: u64,
    ) -> Result<Bodies, CodingError> {
        let (identity, gzip) = match coding {
            Encoding::Identity => (primary, None),
            Encoding::Gzip => (gunzip(&primary, max_tile)?, Some(Bytes::from(primary))),
            Encoding::Brotli => (unbrotli(&primary, max_tile)?, None),
        };
        Ok(Bodies {
            identity: Bytes::from(identity),
            gzip,
            brotli: brotli.map(Bytes::from),
            quick: None,
        })
    }

    /// Checks every form against the digest the tile was stored with (`etag`, see
    /// [`super::etag_of`]): the identity body's own, and each compressed form decoding to it.
    pub fn verify(&self, etag: &str) -> Result<(), CodingError> {
        if super::etag_of(&self.identity) != etag {
            return Err(CodingError::Mismatch { coding: "identity" });
        }
        // The gzip form was decoded to make the identity one; brotli is decoded here.
        if let Some(brotli) = &self.brotli {
            // It decodes to the identity body or it is damaged: no longer.
            if unbrotli(brotli, self.identity.len() as u64)? != self.identity {
                return Err(CodingError::Mismatch { coding: "br" });
            }
        }
        Ok(())
    }

    /// The form the store keeps as its primary body: gzip where it pays, else identity.
    pub fn primary(&self) -> (Encoding, &Bytes) {
        match &self.gzip {
            Some(gzip) => (Encoding::Gzip, gzip),
            None => (Encoding::Identity, &self.identity),
        }
    }

    /// Bytes held, for the memory cache's weigher.
    pub fn weight(&self) -> usize {
        self.identity.len()
            + self.gzip.as_ref().map_or(0, Bytes::len)
            + self.brotli.as_ref().map_or(0, Bytes::len)
    }

    /// Bytes the durable store keeps.
    pub fn stored_len(&self) -> usize {
        self.primary().1.len() + self.brotli.as_ref().map_or(0, Bytes::len)
    }

    /// The smallest form the client accepts.
    pub fn choose(&self, accepted: &Accepted) -> (Encoding, &Bytes) {
        let mut best = (Encoding::Identity, &self.identity);
        for (coding, body) in [
            (Encoding::Gzip, self.gzip.as_ref()),
            (Encoding::Brotli, self.brotli.as_ref()),
        ] {
            if let Some(body) = body.filter(|_| accepted.allows(coding)) {
                if body.len() < best.1.len() {
                    best = (coding, body);
                }
            }
        }
        best
    }
}

/// What an `Accept-Encoding` header allows (RFC 9110 §12.5.3): codings with a non-zero
/// quality, `*` for any other. Without the header only identity is sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Accepted {
    gzip: bool,
    brotli: bool,
}

impl Accepted {
    pub fn parse<'a>(headers: impl IntoIterator<Item = &'a str>) -> Accepted {
        let mut named_gzip = None;
        let mut named_brotli = None;
        let mut star = None;
        for item in headers.into_iter().flat_map(|h| h.split(',')) {
            let mut parts = item.split(';');
            let name = parts.next().unwrap_or("").trim().to_ascii_lowercase();
            let quality = parts
                .filter_map(|p| {
                    let (name, value) = p.split_once('=')?;
                    name.trim().eq_ignore_ascii_case("q").then_some(value)
                })
                .find_map(|q| q.trim().parse::<f64>().ok())
                .unwrap_or(1.0);
            let allowed = quality > 0.0;
            match name.as_str() {
                "gzip" | "x-gzip" => named_gzip = Some(allowed),
                "br" => named_brotli = Some(allowed),
                "*" => star = Some(allowed),
                _ => {}
            }
        }
        Accepted {
            gzip: named_gzip.or(star).unwrap_or(false),
            brotli: named_brotli.or(star).unwrap_or(false),
        }
    }

    pub fn allows(&self, coding: Encoding) -> bool {
        match coding {
            Encoding::Identity => true,
            Encoding::Gzip => self.gzip,
            Encoding::Brotli => self.brotli,
        }
    }
}

/// A compressed form of a body `original` bytes long, if it is small enough to be worth
/// sending.
fn worth_keeping(original: usize, form: Vec<u8>) -> Option<Bytes> {
    let limit = (original as f64 * WORTH_KEEPING) as usize;
    (form.len() <= limit).then(|| Bytes::from(form))
}

pub fn gzip(data: &[u8]) -> std::io::Result<Vec<u8>> {
    gzip_at(data, GZIP_LEVEL)
}

fn gzip_at(data: &[u8], level: u32) -> std::io::Result<Vec<u8>> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(level));
    encoder.write_all(data)?;
    encoder.finish()
}

fn brotli(data: &[u8], quality: u32) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    {
        let mut writer = brotli::CompressorWriter::new(&mut out, 1 << 16, quality, BROTLI_WINDOW);
        writer.write_all(data)?;
        writer.flush()?;
    }
    Ok(out)
}

fn gunzip(data: &[u8], limit: u64) -> Result<Vec<u8>, CodingError> {
    crate::inflate::gunzip(data, limit).map_err(|source| CodingError::Corrupt {
        coding: "gzip",
        source,
    })
}

fn unbrotli(data: &[u8], limit: u64) -> Result<Vec<u8>, CodingError> {
    crate::inflate::unbrotli(data, limit).map_err(|source| CodingError::Corrupt {
        coding: "br",
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accept_encoding_is_read_with_its_qualities() {
        let both = Accepted::parse(["gzip, deflate, br"]);
        assert!(both.allows(Encoding::Gzip) && both.allows(Encoding::Brotli));
        let none = Accepted::parse([]);
        assert!(!none.allows(Encoding::Gzip) && !none.allows(Encoding::Brotli));
        let refused = Accepted::parse(["br;q=0, *"]);
        assert!(refused.allows(Encoding::Gzip) && !refused.allows(Encoding::Brotli));
        let upper = Accepted::parse(["gzip;Q=0, br"]);
        assert!(!upper.allows(Encoding::Gzip) && upper.allows(Encoding::Brotli));
        let split = Accepted::parse(["deflate", "GZIP;q=0.5"]);
        assert!(split.allows(Encoding::Gzip) && !split.allows(Encoding::Brotli));
        assert!(Accepted::parse(["identity"]).allows(Encoding::Identity));
    }

    #[test]
    fn every_stored_form_decodes_to_the_original() {
        let original: Vec<u8> = (0..50_000u32)
            .flat_map(|i| (i % 251).to_le_bytes())
            .collect();
        let bodies = Bodies::compress(original.clone()).unwrap();
        assert!(bodies.gzip.is_some() && bodies.brotli.is_some());
        let (coding, primary) = bodies.primary();
        assert_eq!(coding, Encoding::Gzip);
        let back = Bodies::from_stored(
            primary.to_vec(),
            coding,
            bodies.brotli.as_ref().map(|b| b.to_vec()),
            1 << 20,
        )
        .unwrap();
        assert_eq!(back, bodies);
        assert_eq!(
            unbrotli(bodies.brotli.as_ref().unwrap(), 1 << 20).unwrap(),
            original
        );
        let (coding, body) = bodies.choose(&Accepted::parse(["gzip, br"]));
        assert_ne!(coding, Encoding::Identity);
        assert!(body.len() < original.len());
        assert_eq!(
            bodies.choose(&Accepted::default()),
            (Encoding::Identity, &bodies.identity)
        );
    }

    #[test]
    fn a_quick_body_has_only_the_form_its_client_takes() {
        let original: Vec<u8> = (0..50_000u32)
            .flat_map(|i| (i % 251).to_le_bytes())
            .collect();
        let both = Accepted::parse(["gzip, br"]);
        let gzip_only = Accepted::parse(["gzip"]);
        let br_only = Accepted::parse(["br"]);
        let quick = Bodies::quick(original.clone(), &both).unwrap();
        assert_eq!(quick.quick, Some(Encoding::Gzip));
        assert!(quick.gzip.is_some() && quick.brotli.is_none());
        assert_eq!(
            gunzip(quick.gzip.as_ref().unwrap(), 1 << 20).unwrap(),
            original
        );
        // Its own client, and any that takes gzip, are served; one that takes brotli only
        // waits for the forms kept.
        assert!(!quick.awaits_better_for(&both) && !quick.awaits_better_for(&gzip_only));
        assert!(quick.awaits_better_for(&br_only));
        assert!(!quick.awaits_better_for(&Accepted::default()));

        let brotli = Bodies::quick(original.clone(), &br_only).unwrap();
        assert_eq!(brotli.quick, Some(Encoding::Brotli));
        assert!(brotli.gzip.is_none());
        assert_eq!(
            unbrotli(brotli.brotli.as_ref().unwrap(), 1 << 20).unwrap(),
            original
        );
        assert!(brotli.awaits_better_for(&gzip_only) && !brotli.awaits_better_for(&both));

        let plain = Bodies::quick(original.clone(), &Accepted::default()).unwrap();
        assert_eq!(plain.quick, Some(Encoding::Identity));
        assert!(plain.gzip.is_none() && plain.brotli.is_none());
        assert!(plain.awaits_better_for(&gzip_only) && plain.awaits_better_for(&br_only));

        let kept = Bodies::compress(original).unwrap();
        assert!(!kept.awaits_better_for(&br_only));
        assert!(kept.gzip.as_ref().unwrap().len() <= quick.gzip.as_ref().unwrap().len());
    }

    #[test]
    fn incompressible_data_is_kept_as_it_is() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let noise: Vec<u8> = (0..20_000)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        let bodies = Bodies::compress(noise).unwrap();
        assert_eq!(bodies.gzip, None);
        assert_eq!(bodies.brotli, None);
        assert_eq!(bodies.primary().0, Encoding::Identity);
    }

    #[test]
    fn a_corrupt_stored_body_is_an_error_not_a_panic() {
        let error = Bodies::from_stored(vec![0x1f, 0x8b, 1, 2, 3], Encoding::Gzip, None, 1000);
        assert!(matches!(error, Err(CodingError::Corrupt { .. })));
    }

    #[test]
    fn a_stored_body_longer_than_a_tile_may_be_is_damaged() {
        let bodies = Bodies::compress(vec![0u8; 100_000]).unwrap();
        let (coding, primary) = bodies.primary();
        let error = Bodies::from_stored(primary.to_vec(), coding, None, 50_000).unwrap_err();
        assert!(
            error.to_string().contains("more than 50000 bytes"),
            "{error}"
        );
        // A brotli form that decodes past the identity body is damaged, not decoded whole.
        let mut longer = bodies.clone();
        longer.identity = Bytes::from(vec![0u8; 10]);
        let error = longer.verify(&crate::cache::etag_of(&longer.identity));
        assert!(matches!(
            error,
            Err(CodingError::Corrupt { coding: "br", .. })
        ));
    }
}
