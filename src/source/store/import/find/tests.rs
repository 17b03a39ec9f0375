use super::*;

fn cluster(ways: &[i64], cells: &[(u32, u32)]) -> Cluster {
    Cluster {
        ways: ways.iter().copied().collect(),
        cells: cells.iter().copied().collect(),
        ..Cluster::default()
    }
}

#[test]
fn clusters_that_share_a_cell_are_read_as_one_batch_and_others_apart() {
    let batches = batches(vec![
        cluster(&[1], &[(0, 0), (0, 1)]),
        cluster(&[2], &[(5, 5)]),
        cluster(&[3], &[(0, 1), (0, 2)]),
        cluster(&[4], &[(0, 2), (0, 3)]),
    ]);
    let mut ways: Vec<Vec<i64>> = batches
        .iter()
        .map(|b| b.ways.iter().copied().collect())
        .collect();
    ways.sort();
    assert_eq!(ways, [vec![1, 3, 4], vec![2]]);
    let joined = batches.iter().find(|b| b.ways.contains(&1)).unwrap();
    assert_eq!(joined.cells.len(), 4, "{:?}", joined.cells);
}

#[test]
fn disjoint_sets_join_through_a_chain_and_keep_the_rest_apart() {
    let mut sets = DisjointSets::new(5);
    sets.union(0, 1);
    sets.union(2, 1);
    sets.union(3, 4);
    assert_eq!(sets.find(0), sets.find(2));
    assert_eq!(sets.find(3), sets.find(4));
    assert_ne!(sets.find(0), sets.find(3));
}
