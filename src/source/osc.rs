//! OSM change files (`.osc`, `.osc.gz`): the creates, modifies and deletes that replication
//! servers publish and `osmium derive-changes` writes, read whole (a diff is small beside the
//! store it changes) and checked before anything is applied.
//!
//! Within one file an element may change several times; what counts is its last version. A
//! file whose versions of one element go down is out of order and refused, as is one that is
//! cut short or not an `osmChange` document.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use quick_xml::events::{BytesStart, Event};

use super::node_locations::Decimicro;
use crate::osm::{ElementRef, ElementType, Member, Relation, Tags};

#[derive(Debug, thiserror::Error)]
pub enum OscError {
    #[error("OSM change file {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("OSM change file {path} at byte {position} of its XML: {why}")]
    Invalid {
        path: PathBuf,
        position: u64,
        why: String,
    },
}

/// What a change does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    Create,
    Modify,
    Delete,
}

/// An element as a change leaves it.
#[derive(Debug, Clone, PartialEq)]
pub enum Changed {
    /// A node; `at` is None for a delete that gives no position.
    Node {
        id: i64,
        at: Option<Decimicro>,
        tags: Tags,
    },
    Way {
        id: i64,
        nodes: Vec<i64>,
        tags: Tags,
    },
    Relation(Relation),
}

impl Changed {
    pub fn element(&self) -> ElementRef {
        let (element_type, id) = match self {
            Changed::Node { id, .. } => (ElementType::Node, *id),
            Changed::Way { id, .. } => (ElementType::Way, *id),
            Changed::Relation(r) => (ElementType::Relation, r.id),
        };
        ElementRef { element_type, id }
    }
}

/// One change: the element's last version in the file, with what was done to it.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    pub action: Action,
    pub version: u64,
    pub element: Changed,
}

/// A change file read whole: each element changed once, its last version.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OsmChange {
    pub changes: BTreeMap<ElementRef, Change>,
    /// The newest timestamp of its elements (ISO 8601, as written), when they carry one.
    pub newest: Option<String>,
}

impl OsmChange {
    /// Folds a later file's changes in: its version of an element replaces this one's; a
    /// version older than this one's is out of order (the element named in the error).
    pub fn merge(&mut self, later: OsmChange) -> Result<(), String> {
        for (key, change) in &later.changes {
            if let Some(earlier) = self.changes.get(key) {
                if change.version < earlier.version {
                    return Err(format!(
                        "{} {} comes at version {} after version {}",
                        key.element_type.as_str(),
                        key.id,
                        change.version,
                        earlier.version
                    ));
                }
            }
        }
        self.changes.extend(later.changes);
        if later.newest > self.newest {
            self.newest = later.newest;
        }
        Ok(())
    }
}

/// Seconds since 1970 of an OSM timestamp (`2024-01-02T03:04:05Z`), if it is one.
pub fn seconds_of(timestamp: &str) -> Option<i64> {
    let t = timestamp.trim().strip_suffix('Z')?;
    let (date, time) = t.split_once('T')?;
    let mut date = date.split('-').map(|p| p.parse::<i64>().ok());
    let (year, month, day) = (date.next()??, date.next()??, date.next()??);
    let mut time = time.split(':').map(|p| p.parse::<i64>().ok());
    let (hour, minute, second) = (time.next()??, time.next()??, time.next()??);
    if !(1..=12).contains(&month) || !(1..=31).contains(&day) {
        return None;
    }
    // Days from the civil calendar (Howard Hinnant's algorithm).
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let day_of_year = (153 * ((month + 9) % 12) + 2) / 5 + day - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    let days = era * 146_097 + day_of_era - 719_468;
    Some(days * 86_400 + hour * 3600 + minute * 60 + second)
}

/// Reads a change file, gzip-compressed when its name ends in `.gz`.
pub fn read_osc(path: &Path) -> Result<OsmChange, OscError> {
    let file = std::fs::File::open(path).map_err(|source| OscError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let gzipped = path.extension().is_some_and(|e| e == "gz");
    let reader: Box<dyn Read> = if gzipped {
        Box::new(flate2::read::GzDecoder::new(file))
    } else {
        Box::new(file)
    };
    parse(BufReader::new(reader), path)
}

/// Parses a change document from `input`; `path` names it in errors.
pub fn parse(input: impl BufRead, path: &Path) -> Result<OsmChange, OscError> {
    Parser::new(input, path).run()
}

/// The element being read, until its end tag.
struct Open {
    action: Action,
    version: u64,
    timestamp: Option<String>,
    element: Changed,
    tags: Vec<(String, String)>,
}

struct Parser<'p, R> {
    xml: quick_xml::Reader<R>,
    path: &'p Path,
    action: Option<Action>,
    open: Option<Open>,
    found: OsmChange,
    root_seen: bool,
    root_closed: bool,
}

impl<'p, R: BufRead> Parser<'p, R> {
    fn new(input: R, path: &'p Path) -> Parser<'p, R> {
        Parser {
            xml: quick_xml::Reader::from_reader(input),
            path,
            action: None,
            open: None,
            found: OsmChange::default(),
            root_seen: false,
            root_closed: false,
        }
    }

    fn invalid(&self, why: impl Into<String>) -> OscError {
        OscError::Invalid {
            path: self.path.to_path_buf(),
            position: self.xml.buffer_position(),
            why: why.into(),
        }
    }

    fn run(mut self) -> Result<OsmChange, OscError> {
        let mut buffer = Vec::new();
        loop {
            buffer.clear();
            let event = match self.xml.read_event_into(&mut buffer) {
                Ok(event) => event.into_owned(),
                Err(quick_xml::Error::Io(error)) => {
                    return Err(self.invalid(format!("it cannot be read to its end: {error}")))
                }
                Err(error) => return Err(self.invalid(error.to_string())),
            };
            match event {
                Event::Start(tag) => self.start(&tag, false)?,
                Event::Empty(tag) => self.start(&tag, true)?,
                Event::End(tag) => self.end(tag.name().as_ref())?,
                Event::Eof => break,
                _ => {}
            }
        }
        if !self.root_closed {
            return Err(self.invalid("it ends before </osmChange>: the file is cut short"));
        }
        Ok(self.found)
    }

    fn start(&mut self, tag: &BytesStart<'_>, empty: bool) -> Result<(), OscError> {
        let name = tag.name();
        let name = name.as_ref();
        if !self.root_seen {
            if name != b"osmChange" {
                return Err(self.invalid("it is not an osmChange document"));
            }
            self.root_seen = true;
            self.root_closed = empty;
            return Ok(());
        }
        match name {
            b"create" | b"modify" | b"delete" => {
                if self.action.is_some() {
                    return Err(self.invalid("an action inside an action"));
                }
                self.action = Some(match name {
                    b"create" => Action::Create,
                    b"modify" => Action::Modify,
                    _ => Action::Delete,
                });
                if empty {
                    self.action = None;
                }
            }
            b"node" | b"way" | b"relation" => {
                self.open_element(tag)?;
                if empty {
                    self.end(name)?;
                }
            }
            b"tag" | b"nd" | b"member" => self.part(tag)?,
            _ => {}
        }
        Ok(())
    }

    fn attributes(&self, tag: &BytesStart<'_>) -> Result<BTreeMap<String, String>, OscError> {
        let mut found = BTreeMap::new();
        for attribute in tag.attributes() {
            let attribute = attribute.map_err(|e| self.invalid(e.to_string()))?;
            let key = String::from_utf8_lossy(attribute.key.as_ref()).into_owned();
            let value = attribute
                .unescape_value()
                .map_err(|e| self.invalid(e.to_string()))?;
            found.insert(key, value.into_owned());
        }
        Ok(found)
    }

    fn open_element(&mut self, tag: &BytesStart<'_>) -> Result<(), OscError> {
        let Some(action) = self.action else {
            return Err(self.invalid("an element outside <create>, <modify> or <delete>"));
        };
        if self.open.is_some() {
            return Err(self.invalid("an element inside an element"));
        }
        let a = self.attributes(tag)?;
        let id: i64 = self.number(&a, "id")?;
        let version = match a.get("version") {
            Some(_) => self.number(&a, "version")?,
            None => 0,
        };
        let element = match tag.name().as_ref() {
            b"node" => {
                let at = match (a.get("lon"), a.get("lat")) {
                    (Some(lon), Some(lat)) => Some(self.position(id, lon, lat)?),
                    _ if action == Action::Delete => None,
                    _ => return Err(self.invalid(format!("node {id} has no lat and lon"))),
                };
                Changed::Node {
                    id,
                    at,
                    tags: Tags::default(),
                }
            }
            b"way" => Changed::Way {
                id,
                nodes: Vec::new(),
                tags: Tags::default(),
            },
            _ => Changed::Relation(Relation {
                id,
                tags: Tags::default(),
                members: Vec::new(),
            }),
        };
        self.open = Some(Open {
            action,
            version,
            timestamp: a.get("timestamp").cloned(),
            element,
            tags: Vec::new(),
        });
        Ok(())
    }

    fn number<T: std::str::FromStr>(
        &self,
        attributes: &BTreeMap<String, String>,
        key: &str,
    ) -> Result<T, OscError> {
        let text = attributes
            .get(key)
            .ok_or_else(|| self.invalid(format!("an element without {key}")))?;
        text.parse()
            .map_err(|_| self.invalid(format!("{key}=\"{text}\" is not a number")))
    }

    fn position(&self, id: i64, lon: &str, lat: &str) -> Result<Decimicro, OscError> {
        let bad = || self.invalid(format!("node {id} lies at lon={lon} lat={lat}"));
        let lon = decimicro(lon).filter(|d| d.unsigned_abs() <= 1_800_000_000);
        let lat = decimicro(lat).filter(|d| d.unsigned_abs() <= 900_000_000);
        match (lon, lat) {
            (Some(lon), Some(lat)) => Ok(Decimicro { lon, lat }),
            _ => Err(bad()),
        }
    }

    /// A tag, a node reference or a member of the element being read.
    fn part(&mut self, tag: &BytesStart<'_>) -> Result<(), OscError> {
        let a = self.attributes(tag)?;
        let name = tag.name();
        let invalid = |why: &str| self.invalid(why.to_string());
        let Some(open) = self.open.as_ref() else {
            return Err(invalid("a tag, nd or member outside an element"));
        };
        let part = match (name.as_ref(), &open.element) {
            (b"tag", _) => match (a.get("k"), a.get("v")) {
                (Some(k), Some(v)) => Part::Tag(k.clone(), v.clone()),
                _ => return Err(invalid("a tag without k and v")),
            },
            (b"nd", Changed::Way { .. }) => Part::Node(self.number(&a, "ref")?),
            (b"member", Changed::Relation(_)) => {
                let element_type = match a.get("type").map(String::as_str) {
                    Some("node") => ElementType::Node,
                    Some("way") => ElementType::Way,
                    Some("relation") => ElementType::Relation,
                    other => return Err(self.invalid(format!("a member of type {other:?}"))),
                };
                Part::Member(Member {
                    element: ElementRef {
                        element_type,
                        id: self.number(&a, "ref")?,
                    },
                    role: a.get("role").cloned().unwrap_or_default(),
                })
            }
            _ => {
                return Err(invalid(
                    "an nd outside a way or a member outside a relation",
                ))
            }
        };
        if let Some(open) = self.open.as_mut() {
            match part {
                Part::Tag(k, v) => open.tags.push((k, v)),
                Part::Node(id) => {
                    if let Changed::Way { nodes, .. } = &mut open.element {
                        nodes.push(id);
                    }
                }
                Part::Member(m) => {
                    if let Changed::Relation(r) = &mut open.element {
                        r.members.push(m);
                    }
                }
            }
        }
        Ok(())
    }

    fn end(&mut self, name: &[u8]) -> Result<(), OscError> {
        match name {
            b"osmChange" => self.root_closed = true,
            b"create" | b"modify" | b"delete" => self.action = None,
            b"node" | b"way" | b"relation" => {
                let Some(open) = self.open.take() else {
                    return Err(self.invalid("an end tag without its element"));
                };
                self.close(open)?;
            }
            _ => {}
        }
        Ok(())
    }

    fn close(&mut self, mut open: Open) -> Result<(), OscError> {
        let tags = Tags::from_pairs(std::mem::take(&mut open.tags));
        match &mut open.element {
            Changed::Node { tags: t, .. } | Changed::Way { tags: t, .. } => *t = tags,
            Changed::Relation(r) => r.tags = tags,
        }
        let key = open.element.element();
        if let Some(earlier) = self.found.changes.get(&key) {
            if open.version < earlier.version {
                return Err(self.invalid(format!(
                    "{} {} comes at version {} after version {}: the changes are out of order",
                    key.element_type.as_str(),
                    key.id,
                    open.version,
                    earlier.version
                )));
            }
        }
        if open.timestamp > self.found.newest {
            self.found.newest = open.timestamp;
        }
        self.found.changes.insert(
            key,
            Change {
                action: open.action,
                version: open.version,
                element: open.element,
            },
        );
        Ok(())
    }
}

enum Part {
    Tag(String, String),
    Node(i64),
    Member(Member),
}

/// A decimal number of degrees in 10⁻⁷ degrees, rounded to the nearest (OSM keeps seven
/// decimals); None when it is not a plain decimal.
fn decimicro(text: &str) -> Option<i32> {
    let (negative, digits) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text.strip_prefix('+').unwrap_or(text)),
    };
    let (whole, fraction) = digits.split_once('.').unwrap_or((digits, ""));
    let plain = |s: &str| s.bytes().all(|b| b.is_ascii_digit());
    if whole.is_empty() && fraction.is_empty() || !plain(whole) || !plain(fraction) {
        return None;
    }
    if whole.len() > 3 {
        return None;
    }
    let whole: i64 = if whole.is_empty() {
        0
    } else {
        whole.parse().ok()?
    };
    let mut units = whole * 10_000_000;
    let mut scale = 1_000_000;
    for (k, b) in fraction.bytes().enumerate() {
        let digit = i64::from(b - b'0');
        if k < 7 {
            units += digit * scale;
            scale /= 10;
        } else {
            if k == 7 && digit >= 5 {
                units += 1;
            }
            break;
        }
    }
    i32::try_from(if negative { -units } else { units }).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps_count_seconds_from_1970() {
        assert_eq!(seconds_of("1970-01-01T00:00:00Z"), Some(0));
        assert_eq!(seconds_of("2024-01-02T03:04:05Z"), Some(1_704_164_645));
        assert_eq!(seconds_of("2000-03-01T00:00:00Z"), Some(951_868_800));
        assert_eq!(seconds_of("2024-13-02T03:04:05Z"), None);
        assert_eq!(seconds_of("yesterday"), None);
    }

    fn read(text: &str) -> Result<OsmChange, OscError> {
        parse(text.as_bytes(), Path::new("test.osc"))
    }

    #[test]
    fn a_change_file_gives_each_element_its_last_version() {
        let found = read(
            r#"<?xml version="1.0"?><osmChange version="0.6">
            <create><node id="1" version="1" lat="43.7384176" lon="-7.4246158" timestamp="2024-01-01T00:00:00Z"><tag k="a" v="b&amp;c"/></node></create>
            <modify><node id="1" version="2" lat="43.7" lon="7.4" timestamp="2024-01-02T00:00:00Z"/>
              <way id="5" version="3"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way></modify>
            <delete><relation id="9" version="4"/><node id="3" version="2"/></delete>
            </osmChange>"#,
        )
        .unwrap();
        assert_eq!(found.changes.len(), 4);
        assert_eq!(found.newest.as_deref(), Some("2024-01-02T00:00:00Z"));
        let node = &found.changes[&ElementRef {
            element_type: ElementType::Node,
            id: 1,
        }];
        assert_eq!(node.action, Action::Modify);
        assert_eq!(
            node.element,
            Changed::Node {
                id: 1,
                at: Some(Decimicro {
                    lon: 74_000_000,
                    lat: 437_000_000
                }),
                tags: Tags::default()
            }
        );
        let way = &found.changes[&ElementRef {
            element_type: ElementType::Way,
            id: 5,
        }];
        match &way.element {
            Changed::Way { nodes, tags, .. } => {
                assert_eq!(nodes, &[1, 2]);
                assert_eq!(tags.get("highway"), Some("primary"));
            }
            other => panic!("{other:?}"),
        }
        let deleted = &found.changes[&ElementRef {
            element_type: ElementType::Node,
            id: 3,
        }];
        assert_eq!(deleted.action, Action::Delete);
    }

    #[test]
    fn a_file_cut_short_is_refused_with_its_position() {
        let text = r#"<osmChange version="0.6"><create><node id="1" version="1" lat="1" lon="2"/>"#;
        let error = read(text).unwrap_err().to_string();
        assert!(error.contains("test.osc at byte"), "{error}");
        assert!(error.contains("cut short"), "{error}");
    }

    #[test]
    fn versions_going_down_are_refused_as_out_of_order() {
        let text = r#"<osmChange><modify><node id="1" version="3" lat="1" lon="2"/><node id="1" version="2" lat="1" lon="2"/></modify></osmChange>"#;
        let error = read(text).unwrap_err().to_string();
        assert!(error.contains("out of order"), "{error}");
    }

    #[test]
    fn malformed_elements_are_refused_by_name() {
        for (text, says) in [
            (r#"<osm><node id="1"/></osm>"#, "not an osmChange"),
            (
                r#"<osmChange><node id="1" lat="1" lon="2"/></osmChange>"#,
                "outside <create>",
            ),
            (
                r#"<osmChange><create><node id="x" lat="1" lon="2"/></create></osmChange>"#,
                "not a number",
            ),
            (
                r#"<osmChange><create><node id="1" lat="91" lon="2"/></create></osmChange>"#,
                "lies at",
            ),
            (
                r#"<osmChange><create><node id="1"/></create></osmChange>"#,
                "no lat and lon",
            ),
            (
                r#"<osmChange><create><way id="1"><nd/></way></create></osmChange>"#,
                "without ref",
            ),
            (r#"<osmChange><create><way id="1"></create>"#, "create"),
        ] {
            let error = read(text).unwrap_err().to_string();
            assert!(error.contains(says), "{text}: {error}");
        }
    }

    #[test]
    fn decimal_degrees_round_to_seven_places() {
        assert_eq!(decimicro("43.7384176"), Some(437_384_176));
        assert_eq!(decimicro("-0.00000005"), Some(-1));
        assert_eq!(decimicro("7"), Some(70_000_000));
        assert_eq!(decimicro("1e5"), None);
        assert_eq!(decimicro("."), None);
        // The smallest i32: no overflow when its size is checked.
        assert_eq!(decimicro("-214.7483648"), Some(i32::MIN));
        let error = read(
            r#"<osmChange><create><node id="1" lat="1" lon="-214.7483648"/></create></osmChange>"#,
        )
        .unwrap_err()
        .to_string();
        assert!(error.contains("lies at"), "{error}");
    }
}
