//! A PNG encoder for the small images tiles carry: 8-bit RGB, no interlacing, every row
//! filtered by its difference to the row above (the images are drawn in flat bands), deflated
//! at a fixed level so the same pixels give the same bytes.

use std::io::Write;

/// An image of `width` × `height` RGB pixels, row by row from the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Rgb {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 3]>,
}

impl Rgb {
    /// An image of one colour.
    pub fn filled(width: u32, height: u32, colour: [u8; 3]) -> Rgb {
        Rgb {
            width,
            height,
            pixels: vec![colour; (width * height) as usize],
        }
    }

    /// Paints the pixels of columns `x0..x1` and rows `y0..y1` (clamped to the image).
    pub fn fill(&mut self, (x0, x1): (u32, u32), (y0, y1): (u32, u32), colour: [u8; 3]) {
        for y in y0..y1.min(self.height) {
            for x in x0..x1.min(self.width) {
                self.pixels[(y * self.width + x) as usize] = colour;
            }
        }
    }
}

/// The PNG file of an image.
pub fn encode(image: &Rgb) -> Vec<u8> {
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut header = Vec::with_capacity(13);
    header.extend_from_slice(&image.width.to_be_bytes());
    header.extend_from_slice(&image.height.to_be_bytes());
    // 8 bits a sample, colour type 2 (RGB), deflate, adaptive filtering, no interlace.
    header.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &header);
    chunk(&mut out, b"IDAT", &deflated(&filtered(image)));
    chunk(&mut out, b"IEND", &[]);
    out
}

/// The scanlines, each led by filter type 2 (up): its bytes less those of the row above.
fn filtered(image: &Rgb) -> Vec<u8> {
    let width = image.width as usize;
    let row_bytes = |y: usize| -> Vec<u8> {
        image.pixels[y * width..(y + 1) * width]
            .iter()
            .flatten()
            .copied()
            .collect()
    };
    let mut data = Vec::with_capacity((width * 3 + 1) * image.height as usize);
    let mut above = vec![0u8; width * 3];
    for y in 0..image.height as usize {
        let row = row_bytes(y);
        data.push(2);
        data.extend(row.iter().zip(&above).map(|(&b, &a)| b.wrapping_sub(a)));
        above = row;
    }
    data
}

fn deflated(data: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::new(9));
    encoder
        .write_all(data)
        .and_then(|()| encoder.finish())
        .expect("deflating into memory cannot fail")
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let mut crc = flate2::Crc::new();
    crc.update(kind);
    crc.update(data);
    out.extend_from_slice(&crc.sum().to_be_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_is_encoded_as_a_png_that_inflates_to_its_rows() {
        let mut image = Rgb::filled(4, 3, [200, 100, 50]);
        image.fill((1, 3), (1, 2), [10, 20, 30]);
        let png = encode(&image);
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(&png[12..16], b"IHDR");
        assert_eq!(&png[16..20], &4u32.to_be_bytes());
        assert_eq!(&png[20..24], &3u32.to_be_bytes());
        // The IDAT chunk inflates to three filtered rows of 1 + 4 × 3 bytes.
        let length = u32::from_be_bytes([png[33], png[34], png[35], png[36]]) as usize;
        assert_eq!(&png[37..41], b"IDAT");
        let mut rows = Vec::new();
        std::io::Read::read_to_end(
            &mut flate2::read::ZlibDecoder::new(&png[41..41 + length]),
            &mut rows,
        )
        .expect("the image data inflates");
        assert_eq!(rows.len(), 3 * 13);
        // The second row differs from the first where it was painted.
        assert_eq!(&rows[13..17], &[2, 0, 0, 0]);
        assert_eq!(rows[17], 10u8.wrapping_sub(200));
        assert!(png.ends_with(&[0, 0, 0, 0, b'I', b'E', b'N', b'D', 0xae, 0x42, 0x60, 0x82]));
    }
}
