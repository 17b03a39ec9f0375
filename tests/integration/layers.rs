//! Imports run one way. Every `crate::…` and `super::…` path in `src/` (tests beside the code
//! excluded) is read, and each top-level module may name only the modules below it, as
//! ARCHITECTURE.md states; inside a folder the files import each other without a cycle. A
//! back-edge fails here with the file that makes it. Only the features (with the OSM model and
//! its reader) read OSM tags: the layers above take typed features.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Each top-level module and the modules it may import. Everything not named is unknown to it.
const ALLOWED: &[(&str, &[&str])] = &[
    ("tile", &[]),
    ("geodesy", &[]),
    ("geoid", &[]),
    ("panics", &[]),
    ("budget", &[]),
    ("parallel", &["budget"]),
    ("inflate", &[]),
    ("geometry", &["tile"]),
    ("format", &["tile"]),
    ("osm", &["tile", "geometry"]),
    ("features", &["osm", "geometry", "parallel", "tile"]),
    ("terrain", &["geometry", "tile"]),
    (
        "elevation",
        &["features", "terrain", "osm", "geometry", "tile"],
    ),
    (
        "mesh",
        &[
            "budget",
            "elevation",
            "features",
            "terrain",
            "osm",
            "geometry",
            "geodesy",
            "parallel",
            "tile",
        ],
    ),
    (
        "output",
        &[
            "mesh",
            "elevation",
            "features",
            "terrain",
            "osm",
            "geometry",
            "geodesy",
            "geoid",
            "format",
            "tile",
        ],
    ),
    (
        "render",
        &[
            "budget",
            "output",
            "mesh",
            "elevation",
            "features",
            "terrain",
            "osm",
            "geometry",
            "panics",
            "parallel",
            "geoid",
            "format",
            "tile",
        ],
    ),
    ("source", &["osm", "terrain", "geometry", "inflate", "tile"]),
    ("cache", &["format", "inflate", "panics", "tile"]),
    ("config", &["source", "render", "geoid", "format", "tile"]),
    (
        "provider",
        &[
            "config", "source", "render", "output", "features", "terrain", "osm", "cache",
            "format", "tile",
        ],
    ),
    (
        "server",
        &[
            "config", "provider", "cache", "output", "budget", "format", "panics", "tile",
        ],
    ),
    (
        "offline",
        &["provider", "cache", "output", "format", "tile"],
    ),
    (
        "cli",
        &[
            "server", "offline", "provider", "config", "source", "cache", "format", "tile",
        ],
    ),
];

/// External crates only some places may use, and those places (a file, or a folder ending
/// in `/`, under `src/`). The web stack stays in the server, the command line's crates in
/// `cli`, each database client in its store, each file format's reader in its reader, and the
/// pure core (`tile` … `render`) uses no crate that does I/O. Crates not named here (serde,
/// thiserror, tracing, sha2, …) may be used anywhere.
const CRATES: &[(&str, &[&str])] = &[
    ("axum", &["server/"]),
    ("hyper", &["server/"]),
    ("hyper_util", &["server/"]),
    ("http_body_util", &["server/"]),
    ("tower", &["server/"]),
    ("tower_http", &["server/"]),
    ("clap", &["cli/"]),
    ("indicatif", &["cli/"]),
    ("tracing_subscriber", &["cli/"]),
    ("anyhow", &["cli/", "main.rs"]),
    ("figment", &["config.rs"]),
    (
        "tokio",
        &[
            "server/",
            "cli/serve.rs",
            "cache/mod.rs",
            "cache/flight.rs",
            "cache/refine.rs",
            "cache/postgres/",
        ],
    ),
    ("postgres", &["cache/postgres/", "cache/store.rs"]),
    (
        "rusqlite",
        &[
            "cache/sqlite.rs",
            "cache/sqlite/",
            "cache/archive/mbtiles.rs",
            "cache/archive/mod.rs",
            "cache/store.rs",
            "source/store/",
        ],
    ),
    ("pmtiles", &["cache/archive/"]),
    ("ureq", &["source/fetch.rs", "cli/update.rs"]),
    ("osmpbf", &["source/osm_pbf.rs", "source/store/"]),
    ("quick_xml", &["source/osc.rs"]),
    ("zip", &["source/srtm.rs"]),
    ("tiff", &["source/geotiff.rs"]),
    (
        "flate2",
        &["inflate.rs", "cache/", "source/", "output/png.rs"],
    ),
    ("brotli", &["inflate.rs", "cache/"]),
    (
        "moka",
        &[
            "cache/",
            "server/",
            "source/srtm.rs",
            "elevation/solutions.rs",
        ],
    ),
    ("good_lp", &["elevation/lp/reference.rs"]),
    ("gltf_json", &["output/glb.rs", "output/glb/"]),
    ("meshopt", &["output/glb.rs"]),
    (
        "libc",
        &[
            "server/memory.rs",
            "server/connections.rs",
            "provider/osm_source.rs",
            "cache/refine.rs",
        ],
    ),
];

/// Modules the library declares that no layer above may skip: `lib.rs` and `main.rs` wire
/// everything and are not checked.
const ROOTS: &[&str] = &["lib", "main"];

fn src() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, found);
        } else if path.extension().is_some_and(|e| e == "rs") {
            found.push(path);
        }
    }
}

/// The code of a file without its line comments and without the tests beside it: each item
/// under `#[cfg(test)]` (a `mod tests { … }`, a helper) is left out, and everything after it
/// is read.
fn code_of(text: &str) -> String {
    let mut kept = String::new();
    let mut rest = text;
    while let Some(at) = rest.find("#[cfg(test)]") {
        kept.push_str(&rest[..at]);
        rest = &rest[at + "#[cfg(test)]".len()..];
        rest = &rest[item_end(rest)..];
    }
    kept.push_str(rest);
    kept.lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Where the item at the start of `code` ends (a byte offset): after its `;` if it has no
/// body, else after the brace that closes its body. Braces in comments and in string and
/// character literals do not count.
fn item_end(code: &str) -> usize {
    let chars: Vec<(usize, char)> = code.char_indices().collect();
    let at = |i: usize| chars.get(i).map(|&(_, c)| c);
    let mut depth = 0usize;
    let mut i = 0;
    while let Some(c) = at(i) {
        match c {
            ';' if depth == 0 => return chars[i].0 + 1,
            '{' => depth += 1,
            '}' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return chars[i].0 + 1;
                }
            }
            '/' if at(i + 1) == Some('/') => {
                while at(i).is_some_and(|c| c != '\n') {
                    i += 1;
                }
            }
            '/' if at(i + 1) == Some('*') => {
                i += 2;
                while at(i).is_some() && !(at(i) == Some('*') && at(i + 1) == Some('/')) {
                    i += 1;
                }
                i += 1;
            }
            'r' if matches!(at(i + 1), Some('#' | '"')) => {
                let hashes = (i + 1..).take_while(|&j| at(j) == Some('#')).count();
                if at(i + 1 + hashes) == Some('"') {
                    i += 2 + hashes;
                    while at(i).is_some()
                        && !(at(i) == Some('"') && (1..=hashes).all(|h| at(i + h) == Some('#')))
                    {
                        i += 1;
                    }
                    i += hashes;
                }
            }
            '"' => {
                i += 1;
                while at(i).is_some_and(|c| c != '"') {
                    i += if at(i) == Some('\\') { 2 } else { 1 };
                }
            }
            '\'' if at(i + 1) == Some('\\') => {
                i += 2;
                while at(i).is_some_and(|c| c != '\'') {
                    i += 1;
                }
            }
            '\'' if at(i + 2) == Some('\'') => i += 2,
            _ => {}
        }
        i += 1;
    }
    code.len()
}

/// The first names after each `prefix` (`crate::` or `super::`), brace groups opened:
/// `crate::{a, b::c}` names `a` and `b`.
fn names_after(code: &str, prefix: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let mut rest = code;
    while let Some(at) = rest.find(prefix) {
        let before = rest[..at].chars().next_back();
        rest = &rest[at + prefix.len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 0;
            let mut item = String::new();
            for c in group.chars() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        names.extend(first_identifier(&item));
                        item.clear();
                        continue;
                    }
                    _ => {}
                }
                item.push(c);
            }
            names.extend(first_identifier(&item));
        } else {
            names.extend(first_identifier(rest));
        }
    }
    names
}

fn first_identifier(text: &str) -> Option<String> {
    let name: String = text
        .trim_start()
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    (!name.is_empty() && name != "self").then_some(name)
}

/// The top-level module a file belongs to, and its name inside its folder.
fn module_of(relative: &Path) -> (String, String) {
    let mut parts: Vec<String> = relative
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    let top = parts.remove(0);
    let inner = parts.join("/");
    (
        top,
        if inner.is_empty() {
            "mod".into()
        } else {
            inner
        },
    )
}

struct Imports {
    /// (top module, imported top module) → files making that import.
    between: BTreeMap<(String, String), BTreeSet<String>>,
    /// folder → file → files of the same folder it imports.
    within: BTreeMap<String, BTreeMap<String, BTreeSet<String>>>,
}

/// Every `.rs` file under `src/`, by its path relative to `src/`, with its text; the files of
/// tests beside the code (`tests.rs`, declared under `#[cfg(test)]`) are left out.
fn sources() -> Vec<(String, String)> {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    files.retain(|path| path.file_name().is_none_or(|name| name != "tests.rs"));
    files.sort();
    files
        .iter()
        .map(|path| {
            let relative = path.strip_prefix(src()).unwrap();
            (
                relative.to_string_lossy().into_owned(),
                std::fs::read_to_string(path).unwrap(),
            )
        })
        .collect()
}

fn imports(files: &[(String, String)]) -> Imports {
    let mut between: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    let mut within: BTreeMap<String, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (path, text) in files {
        let code = code_of(text);
        let (top, inner) = module_of(Path::new(path));
        let siblings: BTreeSet<String> = names_after(&code, "super::")
            .into_iter()
            .chain(
                names_after(&code, &format!("crate::{top}::"))
                    .into_iter()
                    .filter(|_| inner != "mod"),
            )
            .collect();
        if inner != "mod" {
            let entry = within.entry(top.clone()).or_default();
            entry.entry(inner.clone()).or_default().extend(siblings);
        }
        for used in names_after(&code, "crate::") {
            if used != top {
                between
                    .entry((top.clone(), used))
                    .or_default()
                    .insert(path.clone());
            }
        }
    }
    // Only names that are files of the folder are edges between files.
    for files in within.values_mut() {
        let known: BTreeSet<String> = files.keys().cloned().collect();
        for (file, used) in files.iter_mut() {
            used.retain(|u| known.contains(u) && u != file);
        }
    }
    Imports { between, within }
}

/// The imports against the layers, one line each.
fn back_edges(imports: &Imports) -> Vec<String> {
    let mut back_edges = Vec::new();
    for ((from, to), files) in &imports.between {
        if ROOTS.contains(&from.as_str()) {
            continue;
        }
        let Some(allowed) = allowed(from) else {
            back_edges.push(format!(
                "{from} has no place in the layers of tests/layers.rs"
            ));
            continue;
        };
        if !allowed.contains(&to.as_str()) {
            back_edges.push(format!("{from} → {to} (in {files:?})"));
        }
    }
    back_edges
}

/// The cycles among the files of each folder, one line each.
fn cycles(imports: &Imports) -> Vec<String> {
    imports
        .within
        .iter()
        .filter_map(|(folder, files)| {
            find_cycle(files).map(|cycle| format!("{folder}: {}", cycle.join(" → ")))
        })
        .collect()
}

fn allowed(module: &str) -> Option<&'static [&'static str]> {
    ALLOWED
        .iter()
        .find(|(name, _)| *name == module)
        .map(|(_, allowed)| *allowed)
}

#[test]
fn files_named_tests_are_tests_beside_the_code() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    for path in files.iter().filter(|p| p.ends_with("tests.rs")) {
        let parent = path.parent().unwrap().with_extension("rs");
        let text = std::fs::read_to_string(&parent).unwrap_or_default();
        assert!(
            text.contains("#[cfg(test)]\nmod tests;")
                || text.contains("#[cfg(test)]\npub(crate) mod tests;"),
            "{} is not declared under #[cfg(test)] in {}",
            path.display(),
            parent.display()
        );
    }
}

#[test]
fn every_module_imports_only_the_layers_below_it() {
    let back_edges = back_edges(&imports(&sources()));
    assert!(
        back_edges.is_empty(),
        "imports against the layers:\n{}",
        back_edges.join("\n")
    );
}

#[test]
fn an_import_up_the_layers_is_a_back_edge() {
    let mut files = sources();
    files.push((
        "features/shapes.rs".into(),
        "use crate::mesh::Part;\n".into(),
    ));
    files.push((
        "cache/glb.rs".into(),
        "fn f() { crate::output::glb::write(); }\n".into(),
    ));
    assert_eq!(
        back_edges(&imports(&files)),
        [
            r#"cache → output (in {"cache/glb.rs"})"#,
            r#"features → mesh (in {"features/shapes.rs"})"#,
        ]
    );
}

#[test]
fn a_module_outside_the_layers_is_named() {
    let mut files = sources();
    files.push(("shortcuts.rs".into(), "use crate::tile::TileId;\n".into()));
    assert_eq!(
        back_edges(&imports(&files)),
        ["shortcuts has no place in the layers of tests/layers.rs"]
    );
}

/// The uses of the crates of [`CRATES`] outside their places, one line each.
fn crate_uses(files: &[(String, String)]) -> Vec<String> {
    let mut found = Vec::new();
    for (path, text) in files {
        let code = code_of(text);
        for (name, places) in CRATES {
            let allowed = places.iter().any(|place| match place.strip_suffix('/') {
                Some(folder) => path.starts_with(&format!("{folder}/")),
                None => path == place,
            });
            if !allowed && names_crate(&code, name) {
                found.push(format!("{path} uses {name}"));
            }
        }
    }
    found.sort();
    found
}

/// Whether `code` names the external crate `name`: `name::…`, `use name;` or `use name as …`,
/// not as part of a longer path (`super::name::`) and not where a module of the file has
/// that name.
fn names_crate(code: &str, name: &str) -> bool {
    if code.contains(&format!("mod {name};")) || code.contains(&format!("mod {name} {{")) {
        return false;
    }
    let whole = |at: usize| {
        let before = code[..at].chars().next_back();
        !before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
    };
    let path = format!("{name}::");
    code.match_indices(&path).any(|(at, _)| whole(at))
        || [format!("use {name};"), format!("use {name} as")]
            .iter()
            .any(|form| code.match_indices(form.as_str()).any(|(at, _)| whole(at)))
}

#[test]
fn external_crates_are_used_only_where_their_layer_allows() {
    let uses = crate_uses(&sources());
    assert!(
        uses.is_empty(),
        "crates used outside their places (tests/layers.rs, CRATES):\n{}",
        uses.join("\n")
    );
}

#[test]
fn a_web_crate_in_the_core_and_a_database_client_beside_its_store_are_found() {
    let mut files = sources();
    files.push((
        "elevation/remote.rs".into(),
        "use tokio::net::TcpStream;\nfn f() -> axum::body::Bytes { todo!() }\n".into(),
    ));
    files.push((
        "cache/quota.rs".into(),
        "use postgres as pg;\nfn f(x: super::postgres::Store) {}\n".into(),
    ));
    assert_eq!(
        crate_uses(&files),
        [
            "cache/quota.rs uses postgres",
            "elevation/remote.rs uses axum",
            "elevation/remote.rs uses tokio",
        ]
    );
}

#[test]
fn code_after_the_tests_beside_it_is_still_read() {
    let text = "fn a() {}\n#[cfg(test)]\nmod tests {\n    fn t() { let s = \"}\"; let c = '{'; }\n    // }\n}\nuse crate::mesh::Part;\n";
    let code = code_of(text);
    assert!(code.contains("use crate::mesh::Part;"), "{code}");
    assert!(!code.contains("fn t()"), "{code}");
    let mut files = sources();
    files.push(("features/shapes.rs".into(), text.into()));
    assert_eq!(
        back_edges(&imports(&files)),
        [r#"features → mesh (in {"features/shapes.rs"})"#]
    );
}

/// The modules that may read OSM tags: the model that holds them, the reader that fills it,
/// the features that say what they mean, and the glb writer's metadata table that copies a
/// feature's tags.
const TAG_READERS: &[&str] = &["osm", "source", "features", "output/glb/metadata.rs"];

/// The places outside [`TAG_READERS`] that read tags (`.tags` or the `Tags` type).
fn tag_reads(files: &[(String, String)]) -> Vec<String> {
    files
        .iter()
        .filter(|(path, _)| {
            let top = path.split('/').next().unwrap_or("").trim_end_matches(".rs");
            !TAG_READERS.contains(&top) && !TAG_READERS.contains(&path.as_str())
        })
        .flat_map(|(path, text)| {
            code_of(text)
                .lines()
                .enumerate()
                .filter(|(_, line)| line.contains(".tags") || contains_word(line, "Tags"))
                .map(|(n, line)| format!("{path}:{}: {}", n + 1, line.trim()))
                .collect::<Vec<_>>()
        })
        .collect()
}

fn contains_word(line: &str, word: &str) -> bool {
    line.match_indices(word).any(|(at, _)| {
        let before = line[..at].chars().next_back();
        let after = line[at + word.len()..].chars().next();
        let part = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
        !part(before) && !part(after)
    })
}

#[test]
fn features_are_the_only_readers_of_osm_tags() {
    let reads = tag_reads(&sources());
    assert!(
        reads.is_empty(),
        "OSM tags read outside the features:\n{}",
        reads.join("\n")
    );
}

#[test]
fn a_tag_read_in_elevation_is_found() {
    let mut files = sources();
    files.push((
        "elevation/bridges.rs".into(),
        "fn f(w: &Way) -> bool { w.tags.get(\"bridge\").is_some() }\n".into(),
    ));
    assert_eq!(
        tag_reads(&files),
        ["elevation/bridges.rs:1: fn f(w: &Way) -> bool { w.tags.get(\"bridge\").is_some() }"]
    );
}

#[test]
fn the_layers_themselves_form_no_cycle() {
    // Each module's allowed imports are declared before it in ALLOWED.
    for (index, (module, allowed)) in ALLOWED.iter().enumerate() {
        for below in *allowed {
            let position = ALLOWED.iter().position(|(name, _)| name == below);
            assert!(
                position.is_some_and(|p| p < index),
                "{module} may import {below}, which is not a layer below it"
            );
        }
    }
}

#[test]
fn files_of_a_folder_import_each_other_without_a_cycle() {
    let cycles = cycles(&imports(&sources()));
    assert!(cycles.is_empty(), "cycles:\n{}", cycles.join("\n"));
}

#[test]
fn two_files_that_import_each_other_are_a_cycle() {
    let mut files = sources();
    files.push(("osm/first.rs".into(), "use super::second::B;\n".into()));
    files.push(("osm/second.rs".into(), "use crate::osm::first::A;\n".into()));
    assert_eq!(cycles(&imports(&files)), ["osm: first → second → first"]);
}

/// A cycle in a directed graph, by depth-first search, as the list of its nodes.
fn find_cycle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(node.to_string(), 1);
        path.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            match state.get(next.as_str()).copied().unwrap_or(0) {
                1 => {
                    let start = path.iter().position(|p| p == next).unwrap_or(0);
                    let mut cycle = path[start..].to_vec();
                    cycle.push(next.clone());
                    return Some(cycle);
                }
                0 => {
                    if let Some(cycle) = visit(next, graph, state, path) {
                        return Some(cycle);
                    }
                }
                _ => {}
            }
        }
        path.pop();
        state.insert(node.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in graph.keys() {
        if state.get(node.as_str()).copied().unwrap_or(0) == 0 {
            let mut path = Vec::new();
            if let Some(cycle) = visit(node, graph, &mut state, &mut path) {
                return Some(cycle);
            }
        }
    }
    None
}

#[test]
fn the_reader_finds_imports_in_braces_and_paths() {
    let code = "use crate::{tile::TileId, geometry::{a, b}};\nlet x = crate::osm::Tags::new();\n\
                use super::roads;\nfn f() { my_crate::mesh::x(); }";
    assert_eq!(
        names_after(code, "crate::"),
        ["geometry", "osm", "tile"].map(String::from).into()
    );
    assert_eq!(names_after(code, "super::"), ["roads".to_string()].into());
}

#[test]
fn a_cycle_is_found_and_a_chain_is_not() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
            g.entry(b.to_string()).or_default();
        }
        g
    };
    assert!(find_cycle(&graph(&[("a", "b"), ("b", "c")])).is_none());
    assert_eq!(
        find_cycle(&graph(&[("a", "b"), ("b", "c"), ("c", "a")])),
        Some(["a", "b", "c", "a"].map(String::from).to_vec())
    );
}
