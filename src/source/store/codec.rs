//! The bytes of the OSM store's rows: tags, ways, relations and structure groups, compact and
//! exact. Ids and node references are delta-coded zigzag varints; positions are kept as the
//! PBF gives them (whole steps of 100 nanodegrees, delta-coded) and come back as the same
//! `f64` a PBF reader computes; the floats of a settled structure are kept bit for bit.

use crate::osm::structures::{Above, Chain, ChainWay, Crossed, Crossing, Group, StructureKind};
use crate::osm::{Bounds, ElementRef, ElementType, LonLat, Member, Relation, Tags, Way};
use crate::source::node_locations::Decimicro;

/// A row that cannot be decoded: the store is damaged.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("a stored {what} is damaged: {why}")]
pub struct DecodeError {
    pub what: &'static str,
    pub why: &'static str,
}

/// Writes values into a byte buffer.
#[derive(Debug, Default)]
pub struct Writer(pub Vec<u8>);

impl Writer {
    pub fn unsigned(&mut self, mut value: u64) {
        while value >= 0x80 {
            self.0.push((value as u8) | 0x80);
            value >>= 7;
        }
        self.0.push(value as u8);
    }

    pub fn signed(&mut self, value: i64) {
        self.unsigned(((value << 1) ^ (value >> 63)) as u64);
    }

    pub fn float(&mut self, value: f64) {
        self.0.extend_from_slice(&value.to_bits().to_le_bytes());
    }

    pub fn text(&mut self, value: &str) {
        self.unsigned(value.len() as u64);
        self.0.extend_from_slice(value.as_bytes());
    }

    pub fn tags(&mut self, tags: &Tags) {
        self.unsigned(tags.len() as u64);
        for (k, v) in tags.iter() {
            self.text(k);
            self.text(v);
        }
    }

    /// Bytes, with their length before them.
    pub fn bytes(&mut self, value: &[u8]) {
        self.unsigned(value.len() as u64);
        self.0.extend_from_slice(value);
    }

    /// Ids in order, each as the difference from the one before.
    pub fn ids(&mut self, ids: &[i64]) {
        self.unsigned(ids.len() as u64);
        let mut last = 0i64;
        for &id in ids {
            self.signed(id.wrapping_sub(last));
            last = id;
        }
    }
}

/// Reads values written by [`Writer`].
#[derive(Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
    what: &'static str,
}

impl<'a> Reader<'a> {
    pub fn new(bytes: &'a [u8], what: &'static str) -> Reader<'a> {
        Reader { bytes, what }
    }

    fn damaged(&self, why: &'static str) -> DecodeError {
        DecodeError {
            what: self.what,
            why,
        }
    }

    pub fn unsigned(&mut self) -> Result<u64, DecodeError> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let (&byte, rest) = self
                .bytes
                .split_first()
                .ok_or_else(|| self.damaged("it ends inside a number"))?;
            self.bytes = rest;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(self.damaged("a number runs past 64 bits"))
    }

    pub fn signed(&mut self) -> Result<i64, DecodeError> {
        let value = self.unsigned()?;
        Ok(((value >> 1) as i64) ^ -((value & 1) as i64))
    }

    pub fn count(&mut self) -> Result<usize, DecodeError> {
        let n = self.unsigned()?;
        // Every counted item takes at least one byte.
        if n > self.bytes.len() as u64 {
            return Err(self.damaged("a count is larger than what follows"));
        }
        Ok(n as usize)
    }

    pub fn float(&mut self) -> Result<f64, DecodeError> {
        if self.bytes.len() < 8 {
            return Err(self.damaged("it ends inside a float"));
        }
        let (head, rest) = self.bytes.split_at(8);
        self.bytes = rest;
        let mut bits = [0u8; 8];
        bits.copy_from_slice(head);
        Ok(f64::from_bits(u64::from_le_bytes(bits)))
    }

    pub fn bytes(&mut self) -> Result<&'a [u8], DecodeError> {
        let n = self.count()?;
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        Ok(head)
    }

    pub fn text(&mut self) -> Result<String, DecodeError> {
        let n = self.count()?;
        let (head, rest) = self.bytes.split_at(n);
        self.bytes = rest;
        String::from_utf8(head.to_vec()).map_err(|_| self.damaged("a text is not UTF-8"))
    }

    pub fn tags(&mut self) -> Result<Tags, DecodeError> {
        let n = self.count()?;
        let mut pairs = Vec::with_capacity(n);
        for _ in 0..n {
            pairs.push((self.text()?, self.text()?));
        }
        Ok(Tags::from_pairs(pairs))
    }

    pub fn ids(&mut self) -> Result<Vec<i64>, DecodeError> {
        let n = self.count()?;
        let mut ids = Vec::with_capacity(n);
        let mut last = 0i64;
        for _ in 0..n {
            last = last.wrapping_add(self.signed()?);
            ids.push(last);
        }
        Ok(ids)
    }

    /// True when everything was read.
    pub fn done(&self) -> Result<(), DecodeError> {
        if self.bytes.is_empty() {
            Ok(())
        } else {
            Err(self.damaged("bytes are left over"))
        }
    }
}

/// A way's row: tags, node ids, and positions in 10⁻⁷ degrees.
pub fn encode_way(tags: &Tags, nodes: &[i64], positions: &[Decimicro]) -> Vec<u8> {
    let mut w = Writer::default();
    w.tags(tags);
    w.ids(nodes);
    let (mut lon, mut lat) = (0i64, 0i64);
    for p in positions {
        w.signed(i64::from(p.lon) - lon);
        w.signed(i64::from(p.lat) - lat);
        (lon, lat) = (i64::from(p.lon), i64::from(p.lat));
    }
    w.0
}

/// A way as the extract gives it: its tags and every node it names.
pub fn encode_raw_way(tags: &Tags, refs: &[i64]) -> Vec<u8> {
    let mut w = Writer::default();
    w.tags(tags);
    w.ids(refs);
    w.0
}

pub fn decode_raw_way(bytes: &[u8]) -> Result<(Tags, Vec<i64>), DecodeError> {
    let mut r = Reader::new(bytes, "raw way");
    let tags = r.tags()?;
    let refs = r.ids()?;
    r.done()?;
    Ok((tags, refs))
}

pub fn decode_way(id: i64, bytes: &[u8]) -> Result<Way, DecodeError> {
    let mut r = Reader::new(bytes, "way");
    let tags = r.tags()?;
    let nodes = r.ids()?;
    let mut positions = Vec::with_capacity(nodes.len());
    let (mut lon, mut lat) = (0i64, 0i64);
    for _ in 0..nodes.len() {
        let out_of_range = DecodeError {
            what: "way",
            why: "a position is out of range",
        };
        lon = lon.checked_add(r.signed()?).ok_or(out_of_range.clone())?;
        lat = lat.checked_add(r.signed()?).ok_or(out_of_range)?;
        let at = Decimicro {
            lon: i32::try_from(lon).map_err(|_| r.damaged("a longitude is out of range"))?,
            lat: i32::try_from(lat).map_err(|_| r.damaged("a latitude is out of range"))?,
        };
        let (lon, lat) = at.lon_lat();
        positions.push(LonLat { lon, lat });
    }
    r.done()?;
    Ok(Way {
        id,
        tags,
        nodes,
        positions,
    })
}

fn element_type_code(t: ElementType) -> u64 {
    match t {
        ElementType::Node => 0,
        ElementType::Way => 1,
        ElementType::Relation => 2,
    }
}

/// A relation's row: tags and members.
pub fn encode_relation(relation: &Relation) -> Vec<u8> {
    let mut w = Writer::default();
    w.tags(&relation.tags);
    w.unsigned(relation.members.len() as u64);
    for member in &relation.members {
        w.unsigned(element_type_code(member.element.element_type));
        w.signed(member.element.id);
        w.text(&member.role);
    }
    w.0
}

pub fn decode_relation(id: i64, bytes: &[u8]) -> Result<Relation, DecodeError> {
    let mut r = Reader::new(bytes, "relation");
    let tags = r.tags()?;
    let n = r.count()?;
    let mut members = Vec::with_capacity(n);
    for _ in 0..n {
        let element_type = match r.unsigned()? {
            0 => ElementType::Node,
            1 => ElementType::Way,
            2 => ElementType::Relation,
            _ => return Err(r.damaged("a member's type is unknown")),
        };
        let id = r.signed()?;
        members.push(Member {
            element: ElementRef { element_type, id },
            role: r.text()?,
        });
    }
    r.done()?;
    Ok(Relation { id, tags, members })
}

fn positions(w: &mut Writer, positions: &[LonLat]) {
    w.unsigned(positions.len() as u64);
    for p in positions {
        w.float(p.lon);
        w.float(p.lat);
    }
}

fn read_positions(r: &mut Reader<'_>) -> Result<Vec<LonLat>, DecodeError> {
    let n = r.count()?;
    (0..n)
        .map(|_| {
            Ok(LonLat {
                lon: r.float()?,
                lat: r.float()?,
            })
        })
        .collect()
}

/// A structure group's row, its ways named by id through `way_id` (the group holds indices
/// into the ways it was found among).
pub fn encode_group(group: &Group, way_id: &dyn Fn(u32) -> i64) -> Vec<u8> {
    let mut w = Writer::default();
    w.unsigned(group.chains.len() as u64);
    for chain in &group.chains {
        w.unsigned(match chain.kind {
            StructureKind::Bridge => 0,
            StructureKind::Tunnel => 1,
        });
        w.signed(i64::from(chain.layer));
        w.unsigned(chain.ways.len() as u64);
        for cw in &chain.ways {
            w.signed(way_id(cw.way));
            w.unsigned(u64::from(cw.reversed));
        }
        w.ids(&chain.nodes);
        positions(&mut w, &chain.positions);
        w.unsigned(chain.segment_way.len() as u64);
        for &s in &chain.segment_way {
            w.unsigned(u64::from(s));
        }
    }
    w.unsigned(group.crossings.len() as u64);
    for c in &group.crossings {
        w.unsigned(u64::from(c.chain));
        w.unsigned(u64::from(c.segment));
        w.float(c.t);
        match c.other {
            Crossed::Way(way) => {
                w.unsigned(0);
                w.signed(way_id(way));
            }
            Crossed::Chain { chain, segment, t } => {
                w.unsigned(1);
                w.unsigned(u64::from(chain));
                w.unsigned(u64::from(segment));
                w.float(t);
            }
        }
    }
    for value in [
        group.bounds.west,
        group.bounds.south,
        group.bounds.east,
        group.bounds.north,
    ] {
        w.float(value);
    }
    w.unsigned(group.above.len() as u64);
    for above in &group.above {
        w.signed(above.id);
        positions(&mut w, &above.positions);
        w.float(above.depth_m);
    }
    w.0
}

/// A stored group, its ways given as indices by `index_of` (a way it has no index for is a
/// damaged store: the closure of a tile always holds a group's ways).
pub fn decode_group(
    bytes: &[u8],
    index_of: &mut dyn FnMut(i64) -> Option<u32>,
) -> Result<Group, DecodeError> {
    let mut r = Reader::new(bytes, "structure group");
    let mut index = |r: &mut Reader<'_>| -> Result<u32, DecodeError> {
        let id = r.signed()?;
        index_of(id).ok_or_else(|| r.damaged("it names a way the store lacks"))
    };
    let small = |r: &mut Reader<'_>| -> Result<u32, DecodeError> {
        u32::try_from(r.unsigned()?).map_err(|_| r.damaged("an index is out of range"))
    };
    let n = r.count()?;
    let mut chains = Vec::with_capacity(n);
    for _ in 0..n {
        let kind = match r.unsigned()? {
            0 => StructureKind::Bridge,
            1 => StructureKind::Tunnel,
            _ => return Err(r.damaged("a chain's kind is unknown")),
        };
        let layer = i32::try_from(r.signed()?).map_err(|_| r.damaged("a layer is out of range"))?;
        let k = r.count()?;
        let mut ways = Vec::with_capacity(k);
        for _ in 0..k {
            let way = index(&mut r)?;
            ways.push(ChainWay {
                way,
                reversed: r.unsigned()? != 0,
            });
        }
        let nodes = r.ids()?;
        let positions = read_positions(&mut r)?;
        let s = r.count()?;
        let segment_way = (0..s).map(|_| small(&mut r)).collect::<Result<_, _>>()?;
        chains.push(Chain {
            kind,
            layer,
            ways,
            nodes,
            positions,
            segment_way,
        });
    }
    let n = r.count()?;
    let mut crossings = Vec::with_capacity(n);
    for _ in 0..n {
        let chain = small(&mut r)?;
        let segment = small(&mut r)?;
        let t = r.float()?;
        let other = match r.unsigned()? {
            0 => Crossed::Way(index(&mut r)?),
            1 => Crossed::Chain {
                chain: small(&mut r)?,
                segment: small(&mut r)?,
                t: r.float()?,
            },
            _ => return Err(r.damaged("a crossing's kind is unknown")),
        };
        crossings.push(Crossing {
            chain,
            segment,
            t,
            other,
        });
    }
    let bounds = Bounds {
        west: r.float()?,
        south: r.float()?,
        east: r.float()?,
        north: r.float()?,
    };
    let n = r.count()?;
    let mut above = Vec::with_capacity(n);
    for _ in 0..n {
        above.push(Above {
            id: r.signed()?,
            positions: read_positions(&mut r)?,
            depth_m: r.float()?,
        });
    }
    r.done()?;
    Ok(Group {
        chains,
        crossings,
        bounds,
        above,
    })
}

/// Positions in degrees, bit for bit (where a bridge passes over a way).
pub fn encode_positions(list: &[LonLat]) -> Vec<u8> {
    let mut w = Writer::default();
    positions(&mut w, list);
    w.0
}

pub fn decode_positions(bytes: &[u8]) -> Result<Vec<LonLat>, DecodeError> {
    let mut r = Reader::new(bytes, "list of positions");
    let list = read_positions(&mut r)?;
    r.done()?;
    Ok(list)
}

/// A way's joints: each joint node with the ways through it.
pub type WayJoints = Vec<(i64, Vec<i64>)>;

pub fn encode_joints(joints: &[(i64, Vec<i64>)]) -> Vec<u8> {
    let mut w = Writer::default();
    w.unsigned(joints.len() as u64);
    for (node, ways) in joints {
        w.signed(*node);
        w.ids(ways);
    }
    w.0
}

pub fn decode_joints(bytes: &[u8]) -> Result<WayJoints, DecodeError> {
    let mut r = Reader::new(bytes, "list of joints");
    let n = r.count()?;
    let mut joints = Vec::with_capacity(n);
    for _ in 0..n {
        joints.push((r.signed()?, r.ids()?));
    }
    r.done()?;
    Ok(joints)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_way_comes_back_as_it_went_in() {
        let tags = Tags::from_pairs([("highway", "primary"), ("name", "Boulevard")]);
        let nodes = [5i64, 3, 1_000_000_000_000, -2];
        let at = [
            (74_123_456, 437_654_321),
            (-1, 0),
            (1_800_000_000, -900_000_000),
            (7, 7),
        ]
        .map(|(lon, lat)| Decimicro { lon, lat });
        let way = decode_way(9, &encode_way(&tags, &nodes, &at)).unwrap();
        assert_eq!(way.tags, tags);
        assert_eq!(way.nodes, nodes);
        let expected: Vec<LonLat> = at
            .iter()
            .map(|p| {
                let (lon, lat) = p.lon_lat();
                LonLat { lon, lat }
            })
            .collect();
        assert_eq!(way.positions, expected);
    }

    #[test]
    fn a_damaged_row_is_an_error_not_a_panic() {
        let tags = Tags::from_pairs([("building", "yes")]);
        let row = encode_way(&tags, &[1, 2], &[Decimicro { lon: 1, lat: 2 }; 2]);
        for cut in 0..row.len() {
            assert!(decode_way(1, &row[..cut]).is_err(), "cut at {cut}");
        }
        assert!(decode_group(&[0xff; 12], &mut |_| Some(0)).is_err());
    }
}
