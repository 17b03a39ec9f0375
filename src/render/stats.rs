//! What a render measured: the time of each stage, and the counts of the tile it made.

use super::*;

/// Time spent in each stage of a render.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// OSM elements into surfaces, buildings and the other features.
    pub features: Duration,
    /// Bridges and tunnels settled by the LP, and the ground they reshape: what settling them
    /// took beyond the features and the ground roads, settled beside it.
    pub structures: Duration,
    /// Ground roads held to their grade by the LP.
    pub roads: Duration,
    /// The ground triangulated with the features stitched in, settled elevations on its
    /// vertices.
    pub triangulation: Duration,
    /// A normal for every ground vertex.
    pub normals: Duration,
    /// The ground's triangles sorted into the tile's parts.
    pub ground: Duration,
    /// Buildings, barriers, bridges and tunnels, power lines, trees and objects meshed: what it
    /// took beyond the ground's parts, made beside the buildings.
    pub shapes: Duration,
    /// The glb or quantized-mesh written.
    pub encode: Duration,
}

impl StageTimings {
    /// The stages' names, in the order they run, as `--timings` and `/metrics` show them.
    pub const NAMES: [&'static str; 8] = [
        "features",
        "structures",
        "roads",
        "triangulation",
        "normals",
        "ground",
        "shapes",
        "encode",
    ];

    /// Each stage's time, in the order of [`StageTimings::NAMES`].
    pub fn stages(&self) -> [Duration; 8] {
        [
            self.features,
            self.structures,
            self.roads,
            self.triangulation,
            self.normals,
            self.ground,
            self.shapes,
            self.encode,
        ]
    }

    pub fn total(&self) -> Duration {
        self.stages().iter().sum()
    }

    /// The timings of the stages whose times are given in the order of [`StageTimings::NAMES`].
    fn from_stages(stages: [Duration; 8]) -> StageTimings {
        let [features, structures, roads, triangulation, normals, ground, shapes, encode] = stages;
        StageTimings {
            features,
            structures,
            roads,
            triangulation,
            normals,
            ground,
            shapes,
            encode,
        }
    }

    /// Adds the stages of another format made from the same render: what both spent before
    /// encoding was spent once (the longer of the two: a terrain has no shapes), and each
    /// encoded its own.
    pub fn add_shared(&mut self, other: StageTimings) {
        let encode = self.encode + other.encode;
        let mut stages = self.stages();
        for (mine, theirs) in stages.iter_mut().zip(other.stages()) {
            *mine = (*mine).max(theirs);
        }
        *self = StageTimings {
            encode,
            ..StageTimings::from_stages(stages)
        };
    }
}

impl std::ops::AddAssign for StageTimings {
    /// Each stage's time added: what several renders spent, stage by stage.
    fn add_assign(&mut self, other: StageTimings) {
        let mut stages = self.stages();
        for (mine, theirs) in stages.iter_mut().zip(other.stages()) {
            *mine += theirs;
        }
        *self = StageTimings::from_stages(stages);
    }
}

/// Counts that describe a rendered tile.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RenderStats {
    pub triangles: usize,
    pub vertices: usize,
    pub primitives: usize,
    pub features_by_class: BTreeMap<&'static str, usize>,
    pub glb_bytes: usize,
    /// Ground triangles dropped because they have no area once positions are `f32`.
    pub slivers_dropped: usize,
    /// Interior terrain samples the adaptive mesh needed.
    pub ground_vertices_inserted: usize,
    /// Triangles of the ground (terrain, roads, railways, water; not under buildings).
    pub ground_triangles: usize,
    pub edge_vertices: usize,
    /// Trees planted (instances).
    pub trees: usize,
    /// Street-level objects placed (instances).
    pub objects: usize,
    /// The elevation LPs of the bridges and tunnels that reach the tile and of its ground
    /// roads: variables, constraints, components solved, and soft constraints violated.
    pub lp_variables: usize,
    pub lp_constraints: usize,
    pub lp_components: usize,
    pub lp_violations: usize,
    /// Of those, the ground roads': stretches settled by the LP, variables, constraints and
    /// soft constraints violated.
    pub road_stretches_settled: usize,
    pub road_lp_variables: usize,
    pub road_lp_constraints: usize,
    pub road_lp_violations: usize,
}

impl RenderStats {
    /// The counts of a tile made of `parts` and `instanced` models from `prepared`.
    pub(super) fn of(
        prepared: &Prepared<'_>,
        parts: &BTreeMap<Part, MeshBuffers>,
        instanced: &BTreeMap<mesh::models::Model, mesh::instances::Instances>,
        slivers: usize,
        glb_bytes: usize,
    ) -> RenderStats {
        let Prepared {
            feature_set,
            ground,
            structures,
            road_profiles,
            ..
        } = prepared;
        let tolerance = crate::output::debug::VIOLATION_TOLERANCE_M;
        let road_violations = road_profiles
            .violations
            .iter()
            .filter(|r| r.violation > tolerance)
            .count();
        RenderStats {
            triangles: parts.values().map(MeshBuffers::triangle_count).sum(),
            vertices: parts.values().map(|b| b.positions.len()).sum(),
            primitives: parts.values().filter(|b| !b.is_empty()).count(),
            features_by_class: FeatureClass::ALL
                .iter()
                .map(|&c| (c.as_str(), feature_set.count(c)))
                .collect(),
            glb_bytes,
            slivers_dropped: slivers,
            ground_vertices_inserted: ground.inserted,
            ground_triangles: ground.triangles.len() - ground.removed,
            edge_vertices: ground.edge_vertices,
            trees: instanced
                .iter()
                .filter(|(model, _)| matches!(model, mesh::models::Model::Tree(..)))
                .map(|(_, t)| t.len())
                .sum(),
            objects: instanced
                .iter()
                .filter(|(model, _)| matches!(model, mesh::models::Model::Object(_)))
                .map(|(_, t)| t.len())
                .sum(),
            lp_variables: structures.iter().map(|s| s.variables).sum::<usize>()
                + road_profiles.variables,
            lp_constraints: structures.iter().map(|s| s.constraints).sum::<usize>()
                + road_profiles.constraints,
            lp_components: structures.iter().map(|s| s.components).sum::<usize>()
                + road_profiles.components,
            lp_violations: structures
                .iter()
                .map(|s| s.violations(tolerance).count())
                .sum::<usize>()
                + road_violations,
            road_stretches_settled: road_profiles.settled,
            road_lp_variables: road_profiles.variables,
            road_lp_constraints: road_profiles.constraints,
            road_lp_violations: road_violations,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_made_from_one_render_count_its_stages_once_and_each_encoding() {
        let ms = Duration::from_millis;
        let glb = StageTimings {
            features: ms(10),
            triangulation: ms(30),
            shapes: ms(20),
            encode: ms(5),
            ..StageTimings::default()
        };
        let terrain = StageTimings {
            shapes: Duration::ZERO,
            encode: ms(2),
            ..glb
        };
        let mut both = StageTimings::default();
        both.add_shared(terrain);
        both.add_shared(glb);
        assert_eq!(both.features, ms(10));
        assert_eq!(both.triangulation, ms(30));
        assert_eq!(both.shapes, ms(20));
        assert_eq!(both.encode, ms(7));
        let mut apart = glb;
        apart += terrain;
        assert_eq!(apart.features, ms(20), "two renders count twice");
    }
}
