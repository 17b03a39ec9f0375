//! The facade textures: one image a glazing, one bay wide and one level high, repeated over
//! the walls by their texture coordinates (see `mesh::facades`). White is wall: the vertex
//! colour the texture multiplies gives each building its own paint, and its windows a tint
//! of it. Every image keeps wall (or a mullion) in its first columns and in the band at the
//! foot of a level, where narrow walls and gables sample it. 64 pixels a side: 5 cm a pixel
//! on a 3 m bay, a few hundred bytes each as PNG, written once in a tile that uses them.

use gltf_json as json;

use super::BinaryBuilder;
use crate::features::facades::Glazing;
use crate::output::png::{self, Rgb};

const SIDE: u32 = 64;
/// Steps of a repeat the compressed texture coordinates count in: the mesh snaps them to these
/// (`mesh::facades::STEPS`), so whole steps are exact.
const STEPS: f64 = crate::mesh::facades::STEPS;
const WALL: [u8; 3] = [255, 255, 255];

/// The texture of a glazing in the tile being written, added with its image the first time.
pub(super) fn texture(builder: &mut BinaryBuilder, glazing: Glazing) -> json::Index<json::Texture> {
    if let Some(&texture) = builder.textures.get(&glazing) {
        return texture;
    }
    let bytes = png::encode(&image(glazing));
    let view = builder.view(&bytes, 4, None);
    let image = builder.root.push(json::Image {
        buffer_view: Some(view),
        mime_type: Some(json::image::MimeType("image/png".to_string())),
        name: Some(format!("facade_{}", glazing.as_str())),
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let sampler = match builder.sampler {
        Some(sampler) => sampler,
        None => {
            let sampler = builder.root.push(json::texture::Sampler {
                mag_filter: Some(json::validation::Checked::Valid(
                    json::texture::MagFilter::Linear,
                )),
                min_filter: Some(json::validation::Checked::Valid(
                    json::texture::MinFilter::LinearMipmapLinear,
                )),
                ..Default::default()
            });
            builder.sampler = Some(sampler);
            sampler
        }
    };
    let texture = builder.root.push(json::Texture {
        name: None,
        sampler: Some(sampler),
        source: image,
        extensions: None,
        extras: Default::default(),
    });
    builder.textures.insert(glazing, texture);
    texture
}

/// The extension that scales whole texels back to repeats of a texture.
pub(super) const TEXTURE_TRANSFORM: &str = "KHR_texture_transform";

/// How a facade material reads its texture: in a compressed tile, whose texture coordinates
/// are whole texels, through a transform that scales them back to repeats.
pub(super) fn texture_info(builder: &mut BinaryBuilder, glazing: Glazing) -> json::texture::Info {
    let index = texture(builder, glazing);
    let extensions = builder.fallback.is_some().then(|| {
        let scale = 1.0 / STEPS;
        json::extensions::texture::Info {
            others: [(
                TEXTURE_TRANSFORM.to_string(),
                serde_json::json!({ "scale": [scale, scale] }),
            )]
            .into_iter()
            .collect(),
        }
    });
    json::texture::Info {
        index,
        tex_coord: 0,
        extensions,
        extras: Default::default(),
    }
}

/// Texture coordinates as an attribute: floats, or in a compressed tile whole texels in 16
/// bits each (`KHR_mesh_quantization`), the texture's transform scaling them back.
pub(super) fn write_uvs(
    builder: &mut BinaryBuilder,
    uvs: &[[f32; 2]],
    compressed: bool,
) -> json::Index<json::Accessor> {
    let (bytes, stride, component_type) = if compressed {
        let texels = |c: f32| {
            let texel = (f64::from(c) * STEPS).round();
            (texel.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16).to_le_bytes()
        };
        let bytes: Vec<u8> = uvs
            .iter()
            .flat_map(|&[u, v]| {
                let ([a, b], [c, d]) = (texels(u), texels(v));
                [a, b, c, d]
            })
            .collect();
        (bytes, 4, json::accessor::ComponentType::I16)
    } else {
        let bytes: Vec<u8> = uvs.iter().flatten().flat_map(|c| c.to_le_bytes()).collect();
        (bytes, 8, json::accessor::ComponentType::F32)
    };
    let view = builder.vertex_view(&bytes, stride);
    builder.root.buffer_views[view.value()].byte_stride = Some(json::buffer::Stride(stride));
    builder.accessor(
        view,
        uvs.len(),
        component_type,
        json::accessor::Type::Vec2,
        None,
    )
}

/// The roughness of a glazing's walls.
pub(super) fn roughness(glazing: Glazing) -> f32 {
    match glazing {
        Glazing::CurtainWall => 0.15,
        _ => 0.85,
    }
}

/// A glazing's image: one bay by one level, its top row at the top of the level.
pub fn image(glazing: Glazing) -> Rgb {
    let mut image = Rgb::filled(SIDE, SIDE, WALL);
    match glazing {
        Glazing::Punched => punched(&mut image),
        Glazing::Ribbon => ribbon(&mut image),
        Glazing::Shopfront => shopfront(&mut image),
        Glazing::CurtainWall => curtain_wall(&mut image),
    }
    image
}

/// Glass darkening downwards (the sky reflected at the top), rows `y0..y1` and columns
/// `x0..x1`; `light` and `dark` are its top and bottom colours.
fn glass(
    image: &mut Rgb,
    (x0, x1): (u32, u32),
    (y0, y1): (u32, u32),
    light: [u8; 3],
    dark: [u8; 3],
) {
    let rows = (y1 - y0).max(1);
    for y in y0..y1 {
        let t = f64::from(y - y0) / f64::from(rows);
        let colour: [u8; 3] = std::array::from_fn(|i| {
            (f64::from(light[i]) + t * (f64::from(dark[i]) - f64::from(light[i]))).round() as u8
        });
        image.fill((x0, x1), (y, y + 1), colour);
    }
}

const FRAME: [u8; 3] = [236, 236, 232];
const SKY: [u8; 3] = [92, 110, 128];
const DEEP: [u8; 3] = [38, 46, 56];

/// A window with a frame, a mullion and a transom, and a sill casting a shadow.
fn punched(image: &mut Rgb) {
    image.fill((18, 46), (12, 48), FRAME);
    glass(image, (20, 44), (14, 46), SKY, DEEP);
    image.fill((31, 33), (14, 46), FRAME);
    image.fill((20, 44), (25, 27), FRAME);
    image.fill((16, 48), (48, 50), [250, 250, 248]);
    image.fill((16, 48), (50, 51), [178, 178, 176]);
}

/// A band of glass across the bay between spandrels, divided by mullions.
fn ribbon(image: &mut Rgb) {
    glass(image, (4, 60), (16, 44), SKY, DEEP);
    for x in [4, 31, 58] {
        image.fill((x, x + 2), (16, 44), [210, 212, 214]);
    }
    image.fill((4, 60), (44, 45), [190, 190, 190]);
}

/// A shop window from the plinth to under the fascia, a door of darker glass in its middle.
fn shopfront(image: &mut Rgb) {
    image.fill((0, SIDE), (4, 11), [150, 150, 150]);
    image.fill((5, 59), (13, 61), [60, 60, 62]);
    glass(image, (7, 57), (15, 61), [120, 134, 146], [50, 58, 66]);
    image.fill((26, 38), (22, 61), [44, 52, 60]);
    image.fill((25, 26), (22, 61), [60, 60, 62]);
    image.fill((38, 39), (22, 61), [60, 60, 62]);
    image.fill((0, SIDE), (61, SIDE), [196, 196, 196]);
}

/// Glass from floor to floor between mullions, an opaque spandrel at each floor.
fn curtain_wall(image: &mut Rgb) {
    glass(image, (0, SIDE), (0, 54), [226, 234, 242], [176, 190, 204]);
    image.fill((0, SIDE), (54, SIDE), [128, 134, 140]);
    for x in [0, 31, 62] {
        image.fill((x, x + 2), (0, SIDE), [150, 154, 158]);
    }
    image.fill((0, SIDE), (0, 2), [150, 154, 158]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_facade_keeps_glass_out_of_the_wall_column_and_band_and_has_glass() {
        // Where `mesh::facades` samples for narrow walls (column 0) and gables (6 % of a level
        // up: row 60).
        for glazing in Glazing::ALL {
            let image = image(glazing);
            let at = |x: u32, y: u32| image.pixels[(y * SIDE + x) as usize];
            let dark = |c: [u8; 3]| c.iter().map(|&v| u32::from(v)).sum::<u32>() < 3 * 120;
            assert!(
                (0..SIDE).all(|y| !dark(at(0, y)) && !dark(at(1, y))),
                "{glazing:?}"
            );
            if glazing != Glazing::Shopfront {
                assert!((0..SIDE).all(|x| !dark(at(x, 60))), "{glazing:?}");
            }
            let glazed = image.pixels.iter().filter(|&&c| c != WALL).count();
            assert!(glazed > 200, "{glazing:?}: {glazed}");
        }
    }
}
