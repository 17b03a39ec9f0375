//! What a tile is made as, and the key it is known by: the glb variants (frame and
//! compression), quantized-mesh with its extensions, a tile in one of them, and the content
//! codings its bodies are kept and sent in. Value types every layer passes around; they know
//! nothing of how a tile is made, stored or served.

use crate::tile::TileId;

/// The frame a tile's coordinates are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub enum Frame {
    /// The flat frame tiles are made in, placed by translation (see `asset.extras`).
    #[default]
    WebMercator,
    /// East-north-up at the tile's centre on WGS 84, placed by a 3D Tiles transform.
    EastNorthUp,
}

/// How a tile's glb is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Variant {
    pub frame: Frame,
    /// `EXT_meshopt_compression` over `KHR_mesh_quantization`.
    pub meshopt: bool,
}

impl Variant {
    pub const ALL: [Variant; 4] = [
        Variant {
            frame: Frame::WebMercator,
            meshopt: false,
        },
        Variant {
            frame: Frame::WebMercator,
            meshopt: true,
        },
        Variant {
            frame: Frame::EastNorthUp,
            meshopt: false,
        },
        Variant {
            frame: Frame::EastNorthUp,
            meshopt: true,
        },
    ];

    /// The variant's name where tiles are stored and listed.
    pub fn name(self) -> &'static str {
        match (self.frame, self.meshopt) {
            (Frame::WebMercator, false) => "glb",
            (Frame::WebMercator, true) => "glb-meshopt",
            (Frame::EastNorthUp, false) => "glb-enu",
            (Frame::EastNorthUp, true) => "glb-enu-meshopt",
        }
    }

    pub fn from_name(name: &str) -> Option<Variant> {
        Variant::ALL.into_iter().find(|v| v.name() == name)
    }
}

/// Which extensions to append.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Extensions {
    pub normals: bool,
    pub watermask: bool,
}

impl Extensions {
    /// Reads the `extensions=` parameter of an `Accept` header
    /// (`application/vnd.quantized-mesh;extensions=octvertexnormals-watermask`).
    pub fn from_accept(accept: &str) -> Extensions {
        let mut extensions = Extensions::default();
        for parameter in accept.split([';', ',']) {
            if let Some(list) = parameter.trim().strip_prefix("extensions=") {
                for name in list.trim_matches('"').split('-') {
                    match name.trim() {
                        "octvertexnormals" | "vertexnormals" => extensions.normals = true,
                        "watermask" => extensions.watermask = true,
                        _ => {}
                    }
                }
            }
        }
        extensions
    }

    /// A short name for cache keys: `terrain`, `terrain-n`, `terrain-w`, `terrain-nw`.
    pub fn key(self) -> &'static str {
        match (self.normals, self.watermask) {
            (false, false) => "terrain",
            (true, false) => "terrain-n",
            (false, true) => "terrain-w",
            (true, true) => "terrain-nw",
        }
    }
}

/// Credit shown wherever tiles are shown, and written into every file of them.
pub const ATTRIBUTION: &str = "© OpenStreetMap contributors, SRTM: NASA/USGS";

/// The formats tiles are made in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Format {
    /// glTF binary in one of its frames and compressions.
    Glb(Variant),
    /// quantized-mesh-1.0 with the extensions asked for.
    Terrain(Extensions),
}

impl Format {
    /// Plain glb in the flat frame: what `/tiles/{z}/{x}/{y}.glb` serves by default.
    pub const GLB: Format = Format::Glb(Variant {
        frame: Frame::WebMercator,
        meshopt: false,
    });

    pub fn as_str(self) -> &'static str {
        match self {
            Format::Glb(variant) => variant.name(),
            Format::Terrain(extensions) => extensions.key(),
        }
    }

    /// Every format, the glb variants first.
    pub fn every() -> impl Iterator<Item = Format> {
        let terrains = [false, true]
            .into_iter()
            .flat_map(|normals| [false, true].map(|watermask| Extensions { normals, watermask }));
        Variant::ALL
            .into_iter()
            .map(Format::Glb)
            .chain(terrains.map(Format::Terrain))
    }

    /// The format a stored name stands for.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::every().find(|format| format.as_str() == name)
    }

    /// The file extension in URLs.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Glb(_) => "glb",
            Format::Terrain(_) => "terrain",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileKey {
    pub tile: TileId,
    pub format: Format,
}
/// A content coding of a response body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Encoding {
    Identity,
    Gzip,
    Brotli,
}

impl Encoding {
    /// The name in `Content-Encoding` and in the store.
    pub fn as_str(self) -> &'static str {
        match self {
            Encoding::Identity => "identity",
            Encoding::Gzip => "gzip",
            Encoding::Brotli => "br",
        }
    }

    pub fn from_name(name: &str) -> Option<Encoding> {
        match name {
            "identity" => Some(Encoding::Identity),
            "gzip" => Some(Encoding::Gzip),
            "br" => Some(Encoding::Brotli),
            _ => None,
        }
    }
}
