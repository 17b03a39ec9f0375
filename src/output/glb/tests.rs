use super::*;

/// A corner as the bits of its position and normal, and its feature.
type Corner = ([u32; 3], [u32; 3], u32);

/// Triangles as their corners, from the first corner in order.
fn triangles(b: &MeshBuffers) -> Vec<[Corner; 3]> {
    let mut out: Vec<_> = b
        .indices
        .chunks_exact(3)
        .map(|t| {
            let mut corners = [0, 1, 2].map(|k| {
                let v = t[k] as usize;
                (
                    b.positions[v].map(f32::to_bits),
                    b.normals[v].map(f32::to_bits),
                    b.feature_ids[v],
                )
            });
            let first = (0..3).min_by_key(|&k| corners[k]).unwrap_or(0);
            corners.rotate_left(first);
            corners
        })
        .collect();
    out.sort();
    out
}

fn fan(unused: usize) -> MeshBuffers {
    let mut b = MeshBuffers::default();
    for _ in 0..unused {
        b.push_vertex([9.0, 9.0, 9.0], [0.0, 1.0, 0.0], 7);
    }
    let centre = b.push_vertex([0.0, 0.32, 0.0], [0.0, -1.0, 0.0], 1);
    let ring: Vec<u32> = (0..12)
        .map(|i| {
            let a = f64::from(i) * std::f64::consts::TAU / 12.0;
            b.push_vertex([a.cos(), 0.4, a.sin()], [a.cos(), -0.5, a.sin()], i % 3)
        })
        .collect();
    for i in 0..12 {
        b.indices.extend([centre, ring[i], ring[(i + 1) % 12]]);
    }
    b
}

#[test]
fn reordering_keeps_every_triangle_and_drops_unused_vertices() {
    for unused in [0, 3] {
        let b = fan(unused);
        let r = reordered(&b);
        assert_eq!(triangles(&b), triangles(&r));
        assert_eq!(r.positions.len(), 13);
    }
}
