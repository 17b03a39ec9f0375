//! Shared helpers of the integration tests: a server on 127.0.0.1:0 with the bundled sample,
//! a glb decoder (the `gltf` crate plus the feature table), the Khronos validator, and a point
//! locator over the ground triangles.
#![allow(dead_code)]

pub mod compressed;
pub mod fixture;
pub mod pg_cluster;
pub mod process;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use terrastitch::cache::{SqliteStore, TileCache};
use terrastitch::config::{Config, ServerConfig};
use terrastitch::provider::{Inputs, Renderer};
use terrastitch::server::{self, AppState};
use terrastitch::TileId;

/// The `terrastitch` binary, run in the repository.
pub fn terrastitch() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_terrastitch"));
    command.current_dir(repo());
    command
}

/// Renders tile `z/x/y` with the command line, in a process of its own, with extra arguments;
/// returns the glb it wrote into `out_dir`. A tile rendered with the same arguments before in
/// this run is not rendered again (the same inputs give the same bytes, which the golden
/// digests and [`render_afresh`] hold to): its bytes are written into `out_dir` as they were.
pub fn render_in_process(tile: &str, args: &[&std::ffi::OsStr], out_dir: &Path) -> Vec<u8> {
    type Made = std::sync::Mutex<BTreeMap<(String, Vec<std::ffi::OsString>), Vec<u8>>>;
    static MADE: std::sync::OnceLock<Made> = std::sync::OnceLock::new();
    let key = (
        tile.to_string(),
        args.iter().map(|a| a.to_os_string()).collect::<Vec<_>>(),
    );
    let made = MADE.get_or_init(Default::default);
    let known = made.lock().unwrap().get(&key).cloned();
    let bytes = match known {
        Some(bytes) => bytes,
        None => {
            let bytes = render_afresh(tile, args, out_dir);
            made.lock().unwrap().insert(key, bytes.clone());
            bytes
        }
    };
    let file = out_dir.join(format!("{}.glb", tile.replace('/', "_")));
    std::fs::write(&file, &bytes).expect("tile written");
    bytes
}

/// As [`render_in_process`], always in a new process.
pub fn render_afresh(tile: &str, args: &[&std::ffi::OsStr], out_dir: &Path) -> Vec<u8> {
    let file = out_dir.join(format!("{}.glb", tile.replace('/', "_")));
    let output = terrastitch()
        .args(["render", tile])
        .args(args)
        .arg("-o")
        .arg(&file)
        .output()
        .expect("terrastitch runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    std::fs::read(&file).expect("tile written")
}

/// The ten Monaco tiles: the coast with the sea and the harbours, the hills behind, bridges,
/// tunnels, ponds and streams.
pub const MONACO_TILES: [(u32, u32); 10] = [
    (8527, 5973),
    (8528, 5973),
    (8529, 5973),
    (8530, 5973),
    (8531, 5973),
    (8527, 5974),
    (8528, 5974),
    (8529, 5974),
    (8530, 5974),
    (8531, 5974),
];

/// The glTF nodes of the ground (every class but buildings).
pub const GROUND_NODES: [&str; 5] = ["terrain", "road", "railway", "water", "landcover"];

/// Where along a side of a tile of `size` a vertex lies, if it is on that side.
pub fn along_side(p: &[f32; 3], side: &str, size: f32) -> Option<f32> {
    let (on_side, along) = match side {
        "west" => (p[0] == 0.0, p[2]),
        "east" => (p[0] == size, p[2]),
        "north" => (p[2] == 0.0, p[0]),
        "south" => (p[2] == size, p[0]),
        _ => unreachable!(),
    };
    on_side.then_some(along)
}

/// Ground vertices (every ground class) on one side of a tile, as bit patterns of
/// (y, along, normal): a normal that differs would show as a lighting seam.
pub fn ground_edge(tile: &DecodedTile, side: &str) -> BTreeSet<(u32, u32, [u32; 3])> {
    let size = tile.tile_size() as f32;
    let mut vertices = BTreeSet::new();
    for node in GROUND_NODES {
        for primitive in tile.primitives(node) {
            for (p, normal) in primitive.positions.iter().zip(&primitive.normals) {
                if let Some(along) = along_side(p, side, size) {
                    vertices.insert((p[1].to_bits(), along.to_bits(), normal.map(f32::to_bits)));
                }
            }
        }
    }
    vertices
}

/// Runs a browser check of `tests/js` with Node (`node SCRIPT ARGS…`) off the async executor
/// and returns the JSON report it prints; the artefacts folder `tests/artifacts/{folder}` is
/// made first.
pub async fn browser_check(script: &str, folder: &str, args: Vec<String>) -> serde_json::Value {
    assert!(
        repo()
            .join("tests/js/node_modules/playwright-core")
            .exists(),
        "playwright-core is not installed: run `make test` (it runs npm ci in tests/js)"
    );
    std::fs::create_dir_all(repo().join("tests/artifacts").join(folder)).unwrap();
    let script = repo().join("tests/js").join(script);
    let output = tokio::task::spawn_blocking(move || {
        Command::new("node")
            .arg(script)
            .args(args)
            .output()
            .expect("node runs")
    })
    .await
    .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    serde_json::from_str(stdout.trim()).unwrap_or_else(|_| {
        panic!(
            "no report:\n{stdout}\n{}",
            String::from_utf8_lossy(&output.stderr)
        )
    })
}

/// A box just inside the tiles x0..=x1, y0..=y1 at zoom 14.
pub fn bbox(x0: u32, x1: u32, y0: u32, y1: u32) -> String {
    let nw = TileId {
        z: 14,
        x: x0,
        y: y0,
    }
    .bounds();
    let se = TileId {
        z: 14,
        x: x1,
        y: y1,
    }
    .bounds();
    let inset = 1e-5;
    format!(
        "{},{},{},{}",
        nw.west + inset,
        se.south + inset,
        se.east - inset,
        nw.north - inset
    )
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The whole data's index of sources read into memory.
pub fn whole(sources: &Inputs) -> &terrastitch::osm::OsmIndex {
    sources
        .osm
        .index()
        .expect("the sources are read into memory")
}

/// The elements near `tile`, of sources read into memory.
pub fn selection(sources: &Inputs, tile: TileId) -> terrastitch::osm::index::Selection<'_> {
    whole(sources).query(tile, terrastitch::provider::inputs::QUERY_MARGIN_DEG)
}

pub fn sample_osm() -> PathBuf {
    repo().join("data/monaco-osrm-2016.osm.pbf")
}

pub fn sample_srtm() -> PathBuf {
    repo().join("data")
}

/// A server running in this process.
pub struct TestServer {
    pub base: String,
    pub state: AppState,
    /// What it renders with, when it renders.
    pub renderer: Option<std::sync::Arc<Renderer>>,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    handle: Option<tokio::task::JoinHandle<()>>,
}

impl TestServer {
    /// Starts a server on the bundled sample with its cache in `cache`.
    pub async fn start(cache: &Path) -> TestServer {
        let config = Config::default();
        let sources = Inputs::open(&[sample_osm()], &sample_srtm(), config.server.zoom)
            .expect("sample data loads");
        let server_config = terrastitch::config::ServerConfig {
            render_threads: 2,
            ..config.server.clone()
        };
        TestServer::start_with(cache, sources, &server_config).await
    }

    /// Starts a server on `sources` with its cache in `cache` and the given settings.
    pub async fn start_with(
        cache: &Path,
        sources: Inputs,
        server_config: &ServerConfig,
    ) -> TestServer {
        let renderer = Renderer::new(sources, Config::default().render, server_config.zoom);
        TestServer::start_rendering(cache, renderer, server_config).await
    }

    /// Starts a server rendering with `renderer`, with its cache in `cache`.
    pub async fn start_rendering(
        cache: &Path,
        renderer: Renderer,
        server_config: &ServerConfig,
    ) -> TestServer {
        let state = TestServer::state(cache, server_config);
        let renderer = std::sync::Arc::new(renderer.with_solutions(state.work.solutions.clone()));
        state.provide(renderer.clone());
        let mut server = TestServer::start_state(state).await;
        server.renderer = Some(renderer);
        server
    }

    /// The inputs it renders from.
    pub fn inputs(&self) -> &Inputs {
        self.renderer.as_ref().expect("a rendering server").inputs()
    }

    /// A server's state with its cache in `cache`, without sources yet.
    pub fn state(cache: &Path, server_config: &ServerConfig) -> AppState {
        let store = SqliteStore::open(cache, None).expect("cache opens");
        let tile_cache = TileCache::new(std::sync::Arc::new(store), 64 << 20);
        AppState::new(tile_cache, server_config)
    }

    /// Starts a server with this state.
    pub async fn start_state(state: AppState) -> TestServer {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .expect("bind");
        let base = format!("http://{}", listener.local_addr().expect("address"));
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let serving = state.clone();
        let handle = tokio::spawn(async move {
            server::serve(listener, serving, async {
                let _ = rx.await;
            })
            .await
            .expect("server runs");
        });
        TestServer {
            base,
            state,
            renderer: None,
            shutdown: Some(tx),
            handle: Some(handle),
        }
    }

    /// A `GET` of `path` with extra request headers.
    pub async fn get(&self, path: &str, headers: &[(&str, &str)]) -> reqwest::Response {
        let mut request = reqwest::Client::new().get(self.url(path));
        for (name, value) in headers {
            request = request.header(*name, *value);
        }
        request.send().await.expect("request reaches the server")
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    pub async fn stop(mut self) {
        if let Some(tx) = self.shutdown.take() {
            let _ = tx.send(());
        }
        if let Some(handle) = self.handle.take() {
            let _ = handle.await;
        }
    }

    /// The value of a counter in `/metrics`.
    pub async fn metric(&self, name: &str) -> f64 {
        let text = reqwest::get(self.url("/metrics"))
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        metric_in(&text, name).unwrap_or_else(|| panic!("metric {name} missing from:\n{text}"))
    }
}

/// The value of the unlabelled metric `name` in a Prometheus text.
pub fn metric_in(text: &str, name: &str) -> Option<f64> {
    text.lines().find_map(|line| {
        let (metric, value) = line.split_once(' ')?;
        (metric == name).then(|| value.trim().parse().ok())?
    })
}

/// One primitive's vertices.
#[derive(Debug, Default, Clone)]
pub struct Primitive {
    pub material: String,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub feature_ids: Vec<u32>,
    pub indices: Vec<u32>,
    /// Texture coordinates, where the primitive is textured.
    pub uvs: Vec<[f32; 2]>,
    /// Colours (linear RGBA), where its vertices carry their own.
    pub colours: Vec<[u8; 4]>,
}

impl Primitive {
    pub fn triangles(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        self.indices
            .chunks_exact(3)
            .map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
    }
}

/// A row of the feature table.
#[derive(Debug, Clone, PartialEq)]
pub struct Feature {
    pub osm_type: String,
    pub osm_id: i64,
    pub class: String,
    pub name: String,
    pub tags: serde_json::Map<String, serde_json::Value>,
    /// The `roof:shape` inferred for it, empty where none was.
    pub inferred_roof_shape: String,
}

#[derive(Debug)]
pub struct DecodedTile {
    /// Primitives by node name.
    pub nodes: BTreeMap<String, Vec<Primitive>>,
    /// Names of the nodes drawn as instances (`EXT_mesh_gpu_instancing`): their positions are
    /// in model space, not in the tile.
    pub instanced: BTreeSet<String>,
    pub features: Vec<Feature>,
    pub asset_extras: serde_json::Value,
}

impl DecodedTile {
    /// The nodes whose vertices are placed in the tile (all but the instanced ones).
    pub fn placed_nodes(&self) -> impl Iterator<Item = (&String, &Vec<Primitive>)> {
        self.nodes
            .iter()
            .filter(|(name, _)| !self.instanced.contains(*name))
    }

    pub fn primitives(&self, node: &str) -> &[Primitive] {
        self.nodes.get(node).map(Vec::as_slice).unwrap_or(&[])
    }

    pub fn tile_size(&self) -> f64 {
        self.asset_extras["terrastitch"]["tile_size_m"]
            .as_f64()
            .expect("tile size in extras")
    }
}

/// Decodes a glb with the `gltf` crate and reads the EXT_structural_metadata table.
pub fn decode(bytes: &[u8]) -> DecodedTile {
    let gltf = gltf::Gltf::from_slice(bytes).expect("valid glb");
    let blob = gltf.blob.clone().expect("binary chunk");
    let view_bytes = |index: usize| -> &[u8] {
        let view = gltf.document.views().nth(index).expect("buffer view");
        &blob[view.offset()..view.offset() + view.length()]
    };
    let mut nodes = BTreeMap::new();
    let mut instanced = BTreeSet::new();
    for node in gltf.document.nodes() {
        let name = node.name().unwrap_or_default().to_string();
        if node.extension_value("EXT_mesh_gpu_instancing").is_some() {
            instanced.insert(name.clone());
        }
        let Some(mesh) = node.mesh() else { continue };
        let mut primitives = Vec::new();
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|_| Some(&blob[..]));
            let positions: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
            let normals: Vec<[f32; 3]> = reader.read_normals().expect("normals").collect();
            let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
            let accessor = primitive
                .get(&gltf::Semantic::Extras("FEATURE_ID_0".to_string()))
                .expect("_FEATURE_ID_0");
            let feature_ids: Vec<u32> = match accessor.data_type() {
                gltf::accessor::DataType::U16 => {
                    gltf::accessor::Iter::<u16>::new(accessor, |_| Some(&blob[..]))
                        .expect("ids")
                        .map(u32::from)
                        .collect()
                }
                gltf::accessor::DataType::F32 => {
                    gltf::accessor::Iter::<f32>::new(accessor, |_| Some(&blob[..]))
                        .expect("ids")
                        .map(|v| v as u32)
                        .collect()
                }
                other => panic!("feature ids of type {other:?}"),
            };
            assert_eq!(feature_ids.len(), positions.len());
            let uvs: Vec<[f32; 2]> = reader
                .read_tex_coords(0)
                .map(|t| t.into_f32().collect())
                .unwrap_or_default();
            let colours: Vec<[u8; 4]> = reader
                .read_colors(0)
                .map(|c| c.into_rgba_u8().collect())
                .unwrap_or_default();
            primitives.push(Primitive {
                material: primitive.material().name().unwrap_or_default().to_string(),
                positions,
                normals,
                feature_ids,
                indices,
                uvs,
                colours,
            });
        }
        nodes.insert(name, primitives);
    }

    let root: serde_json::Value =
        serde_json::to_value(gltf.document.clone().into_json()).expect("json");
    let features = read_features(&root, &view_bytes);
    DecodedTile {
        nodes,
        instanced,
        features,
        asset_extras: root["asset"]["extras"].clone(),
    }
}

/// The rows of a tile's `EXT_structural_metadata` property table.
pub fn read_features<'a>(
    root: &serde_json::Value,
    view_bytes: &dyn Fn(usize) -> &'a [u8],
) -> Vec<Feature> {
    let table = &root["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
    let count = table["count"].as_u64().expect("count") as usize;
    let strings = |property: &str| -> Vec<String> {
        let p = &table["properties"][property];
        let values = view_bytes(p["values"].as_u64().expect("values") as usize);
        let offsets = view_bytes(p["stringOffsets"].as_u64().expect("offsets") as usize);
        let offset = |i: usize| match p["stringOffsetType"].as_str() {
            Some("UINT16") => {
                u16::from_le_bytes(offsets[i * 2..i * 2 + 2].try_into().unwrap()) as usize
            }
            _ => u32::from_le_bytes(offsets[i * 4..i * 4 + 4].try_into().unwrap()) as usize,
        };
        (0..count)
            .map(|i| String::from_utf8(values[offset(i)..offset(i + 1)].to_vec()).expect("utf-8"))
            .collect()
    };
    // An enum column (one byte a row), by the names of its values.
    let enums = |property: &str| -> Vec<String> {
        let p = &table["properties"][property];
        let schema = &root["extensions"]["EXT_structural_metadata"]["schema"];
        let enum_type = schema["classes"]["osm_feature"]["properties"][property]["enumType"]
            .as_str()
            .expect("an enum property");
        let names: BTreeMap<u64, String> = schema["enums"][enum_type]["values"]
            .as_array()
            .expect("enum values")
            .iter()
            .map(|v| {
                let name = v["name"].as_str().expect("name").to_string();
                (v["value"].as_u64().expect("value"), name)
            })
            .collect();
        let values = view_bytes(p["values"].as_u64().expect("values") as usize);
        (0..count)
            .map(|i| names[&u64::from(values[i])].clone())
            .collect()
    };
    let shapes = enums("inferred_roof_shape");
    let ids = view_bytes(
        table["properties"]["osm_id"]["values"]
            .as_u64()
            .expect("ids") as usize,
    );
    let (osm_type, class, tags) = (enums("osm_type"), enums("class"), strings("tags"));
    (0..count)
        .map(|i| {
            let tags: serde_json::Map<String, serde_json::Value> =
                serde_json::from_str(&tags[i]).expect("tags are a JSON object");
            Feature {
                osm_type: osm_type[i].clone(),
                osm_id: i64::from_le_bytes(ids[i * 8..i * 8 + 8].try_into().unwrap()),
                class: class[i].clone(),
                // The name tag, as viewers show it.
                name: tags
                    .get("name")
                    .and_then(|n| n.as_str())
                    .unwrap_or_default()
                    .to_string(),
                tags,
                inferred_roof_shape: Some(shapes[i].clone())
                    .filter(|s| s != "none")
                    .unwrap_or_default(),
            }
        })
        .collect()
}

/// What the Khronos validator says of one file.
#[derive(Debug, serde::Deserialize)]
pub struct Validation {
    pub file: String,
    pub errors: u64,
    pub warnings: u64,
    pub messages: Vec<String>,
    #[serde(rename = "drawCalls")]
    pub draw_calls: Option<u64>,
}

impl Validation {
    /// Fails the test unless the validator found neither errors nor warnings.
    pub fn assert_clean(&self) {
        assert_eq!(
            (self.errors, self.warnings),
            (0, 0),
            "{}: {:?}",
            self.file,
            self.messages
        );
    }
}

/// Runs the Khronos glTF validator (installed by `make test` into tests/js).
pub fn validate(files: &[&Path]) -> Vec<Validation> {
    let script = repo().join("tests/js/validate.mjs");
    assert!(
        repo().join("tests/js/node_modules/gltf-validator").exists(),
        "the glTF validator is not installed: run `make test` (it runs npm ci in tests/js)"
    );
    let output = Command::new("node")
        .arg(script)
        .args(files)
        .output()
        .expect("node runs");
    let reports: Vec<Validation> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|line| serde_json::from_str(line).expect("validator report"))
        .collect();
    check_validator_run(output.status.code(), files, &reports);
    reports
}

/// Fails the test unless the validator ran to its end: one report per file, in order, and
/// the exit code its reports call for (0 when clean, 3 when a file has errors or warnings);
/// a validator that crashed or stopped early passes nothing.
pub fn check_validator_run(code: Option<i32>, files: &[&Path], reports: &[Validation]) {
    let named: Vec<String> = reports.iter().map(|r| r.file.clone()).collect();
    let asked: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    assert_eq!(
        named, asked,
        "the validator reported on other files than asked"
    );
    let dirty = reports.iter().any(|r| r.errors > 0 || r.warnings > 0);
    let expected = if dirty { 3 } else { 0 };
    assert_eq!(
        code,
        Some(expected),
        "the validator exited with {code:?} for reports {reports:?}"
    );
}

/// Finds the ground triangles under a point (in the x/z plane) and interpolates their height.
pub struct GroundLocator {
    triangles: Vec<[[f64; 3]; 3]>,
    cells: usize,
    size: f64,
    grid: Vec<Vec<usize>>,
}

impl GroundLocator {
    pub fn new(triangles: Vec<[[f64; 3]; 3]>, size: f64) -> GroundLocator {
        let cells = 128;
        let mut grid = vec![Vec::new(); cells * cells];
        let cell = |v: f64| ((v / size * cells as f64).floor().max(0.0) as usize).min(cells - 1);
        for (i, t) in triangles.iter().enumerate() {
            let (x0, x1) = (
                t.iter().map(|p| p[0]).fold(f64::MAX, f64::min),
                t.iter().map(|p| p[0]).fold(f64::MIN, f64::max),
            );
            let (z0, z1) = (
                t.iter().map(|p| p[2]).fold(f64::MAX, f64::min),
                t.iter().map(|p| p[2]).fold(f64::MIN, f64::max),
            );
            for row in cell(z0)..=cell(z1) {
                for column in cell(x0)..=cell(x1) {
                    grid[row * cells + column].push(i);
                }
            }
        }
        GroundLocator {
            triangles,
            cells,
            size,
            grid,
        }
    }

    /// The ground a decoded tile draws (its [`GROUND_NODES`]).
    pub fn of_ground(tile: &DecodedTile) -> GroundLocator {
        let triangles = GROUND_NODES
            .iter()
            .flat_map(|n| corners(tile.primitives(n)))
            .collect();
        GroundLocator::new(triangles, tile.tile_size())
    }

    /// The triangles whose box meets a grid cell of the box from `a` to `b` in (x, z).
    pub fn near(&self, a: [f64; 3], b: [f64; 3]) -> BTreeSet<usize> {
        let cell = |v: f64| {
            ((v / self.size * self.cells as f64).floor().max(0.0) as usize).min(self.cells - 1)
        };
        let mut found = BTreeSet::new();
        for row in cell(a[2].min(b[2]))..=cell(a[2].max(b[2])) {
            for column in cell(a[0].min(b[0]))..=cell(a[0].max(b[0])) {
                found.extend(&self.grid[row * self.cells + column]);
            }
        }
        found
    }

    /// Heights of every triangle that contains (x, z) within `tolerance` (barycentric).
    pub fn heights_at(&self, x: f64, z: f64, tolerance: f64) -> Vec<f64> {
        let cell = |v: f64| {
            ((v / self.size * self.cells as f64).floor().max(0.0) as usize).min(self.cells - 1)
        };
        let mut heights = Vec::new();
        for &i in &self.grid[cell(z) * self.cells + cell(x)] {
            let [a, b, c] = self.triangles[i];
            let det = (b[0] - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (b[2] - a[2]);
            if det.abs() < 1e-12 {
                continue;
            }
            let l1 = ((x - a[0]) * (c[2] - a[2]) - (c[0] - a[0]) * (z - a[2])) / det;
            let l2 = ((b[0] - a[0]) * (z - a[2]) - (x - a[0]) * (b[2] - a[2])) / det;
            let l0 = 1.0 - l1 - l2;
            if l0 >= -tolerance && l1 >= -tolerance && l2 >= -tolerance {
                heights.push(l0 * a[1] + l1 * b[1] + l2 * c[1]);
            }
        }
        heights
    }
}

/// The triangles of some primitives as f64 corner positions.
pub fn corners(primitives: &[Primitive]) -> Vec<[[f64; 3]; 3]> {
    primitives
        .iter()
        .flat_map(|p| {
            p.triangles()
                .map(move |t| t.map(|i| p.positions[i].map(f64::from)))
        })
        .collect()
}

/// Where a tunnel runs (its tube, or the approach cut of a tunnel way drawn as road) in a
/// decoded tile: the ground over a tube too shallow for its roof is raised, and a road on it
/// with it.
pub struct TunnelFootprint(GroundLocator);

impl TunnelFootprint {
    pub fn new(tile: &DecodedTile) -> TunnelFootprint {
        let mut triangles = corners(tile.primitives("tunnel"));
        for primitive in tile.primitives("road") {
            for t in primitive.triangles() {
                let row = &tile.features[primitive.feature_ids[t[0]] as usize];
                if row.tags.contains_key("tunnel") {
                    triangles.push(t.map(|i| primitive.positions[i].map(f64::from)));
                }
            }
        }
        TunnelFootprint(GroundLocator::new(triangles, tile.tile_size()))
    }

    /// True within 0.8 m of a tunnel.
    pub fn near(&self, x: f64, z: f64) -> bool {
        [[0.0, 0.0], [0.8, 0.0], [-0.8, 0.0], [0.0, 0.8], [0.0, -0.8]]
            .iter()
            .any(|d| !self.0.heights_at(x + d[0], z + d[1], 1e-6).is_empty())
    }
}

/// The OSM store's tables of elements and facts, each with the columns that order it.
pub const STORE_TABLES: [(&str, &str); 10] = [
    ("nodes", "id"),
    ("ways", "id"),
    ("relations", "id"),
    ("cells", "x, y, kind, id"),
    ("groups", "id"),
    ("group_under", "way, grp"),
    ("joints", "node, way"),
    ("way_facts", "way"),
    ("coastlines", "way"),
    ("far", "zoom, x, y"),
];

/// Every row of `tables` (a table, or a table with a `WHERE`, and the columns to order it by)
/// of an SQLite file, each as `table: [values]`, table after table.
pub fn table_rows(file: &Path, tables: &[(&str, &str)]) -> Vec<String> {
    let db = rusqlite::Connection::open(file).unwrap();
    let mut rows = Vec::new();
    for (table, order) in tables {
        let mut statement = db
            .prepare(&format!("SELECT * FROM {table} ORDER BY {order}"))
            .unwrap();
        let columns = statement.column_count();
        let found = statement
            .query_map([], |row| {
                let values: Vec<rusqlite::types::Value> =
                    (0..columns).map(|k| row.get(k)).collect::<Result<_, _>>()?;
                Ok(format!("{table}: {values:?}"))
            })
            .unwrap();
        rows.extend(found.map(Result::unwrap));
    }
    rows
}

/// The Python the tests run scripts with (`TERRASTITCH_PYTHON`, as `make test` sets it).
pub fn python() -> String {
    std::env::var("TERRASTITCH_PYTHON").unwrap_or_else(|_| "python3".to_string())
}

/// Writes an extract of `ways` (tags and `[lon, lat]` or `[lon, lat, tags]` nodes) with
/// `scripts/ways_extract.py`.
pub fn write_extract(ways: &serde_json::Value, out: &Path) {
    use std::io::Write;
    let mut child = Command::new(python())
        .arg(repo().join("scripts/ways_extract.py"))
        .arg(out)
        .stdin(std::process::Stdio::piped())
        .spawn()
        .expect("python runs");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(ways.to_string().as_bytes())
        .unwrap();
    assert!(child.wait().unwrap().success(), "ways_extract.py failed");
}

/// How long a test waits for something that must happen before it calls it hung.
pub const HUNG: std::time::Duration = std::time::Duration::from_secs(240);

/// Waits until `condition` holds, looking every few milliseconds; fails the test, naming
/// `what`, only when it never does within [`HUNG`] (a bound that means it hung, never a
/// measure of speed).
pub async fn wait_until(what: &str, mut condition: impl FnMut() -> bool) {
    let bound = std::time::Instant::now() + HUNG;
    while !condition() {
        assert!(std::time::Instant::now() < bound, "it hung: {what}");
        tokio::time::sleep(std::time::Duration::from_millis(5)).await;
    }
}

/// Looks every few milliseconds until `probe` gives a value, blocking the thread; fails the
/// test, naming `what`, only when it never does within [`HUNG`].
pub fn wait_for<T>(what: &str, mut probe: impl FnMut() -> Option<T>) -> T {
    let bound = std::time::Instant::now() + HUNG;
    loop {
        if let Some(value) = probe() {
            return value;
        }
        assert!(std::time::Instant::now() < bound, "it hung: {what}");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// Browser checks at once: each drives a software-rendered WebGL page, which keeps about one
/// core busy; more at once would only slow each other.
static BROWSERS: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(2);

/// The turn of one browser check; hold it while the page runs.
pub async fn browser_turn() -> tokio::sync::SemaphorePermit<'static> {
    BROWSERS
        .acquire()
        .await
        .expect("the browsers' turns are never closed")
}

/// A server on the bundled sample whose tile cache the browser checks of this run share (a
/// tile one page made is in the store for the next), with the browser's turn.
pub async fn browser_server() -> (TestServer, tokio::sync::SemaphorePermit<'static>) {
    static CACHE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    let turn = browser_turn().await;
    let cache = CACHE.get_or_init(|| {
        let dir = repo().join("tests/artifacts/browser-cache");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("cache.sqlite")
    });
    (TestServer::start(cache).await, turn)
}
