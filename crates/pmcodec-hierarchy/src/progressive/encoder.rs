//! The encoder side: reclustering frame by frame into deltas and keyframes.

use super::*;

/// Produces frame deltas and keyframes by reclustering.
pub struct Encoder {
    recluster: Reclusterer,
    /// Degeneration node of every triangle in H_f, derived on first request: the stream does not
    /// carry them (see the module docs), so only measurement and tests pay for them.
    node_of: std::sync::OnceLock<Vec<u32>>,
    /// Level-j ancestors of every triangle's corners, for j >= 1 (alive at j iff distinct).
    corners: Vec<Vec<[u32; 3]>>,
    /// The next frame's corners while they are compared with `corners` (kept, not reallocated:
    /// on the horse they are 1.2 MB a frame).
    next_corners: Vec<Vec<[u32; 3]>>,
    /// Whether `corners` follow the frames (see [`Encoder::stop_corners`]).
    follow_corners: bool,
}

impl Encoder {
    /// An encoder starting from the base hierarchy H_0 of `triangles` (with its fine topology).
    pub fn new(base: Hierarchy, topo: FineTopology, triangles: Vec<[u32; 3]>, opts: ReclusterOptions) -> Self {
        let mut enc = Encoder {
            recluster: Reclusterer::new(base, topo, triangles, opts),
            node_of: Default::default(),
            corners: Vec::new(),
            next_corners: Vec::new(),
            follow_corners: true,
        };
        let mut corners = Vec::new();
        enc.fill_corners(&mut corners);
        enc.corners = corners;
        enc
    }

    /// Stops following every level's corners from the next frame on: its deltas then carry no
    /// corner updates and its keyframes no faces. For a caller that sends neither (a container
    /// whose readers derive every band's faces and corner updates from the parent maps,
    /// Kircher & Garland 2005 section 4.1), their upkeep was about a twentieth of the
    /// reclustering thread's time on the horse.
    pub fn stop_corners(&mut self) {
        self.follow_corners = false;
    }

    /// The reclustering options, to change between frames.
    pub fn recluster_options_mut(&mut self) -> &mut ReclusterOptions {
        self.recluster.options_mut()
    }

    /// The current hierarchy H_f.
    pub fn hierarchy(&self) -> &Hierarchy {
        self.recluster.hierarchy()
    }

    /// Every node's quadric and position in H_f for the frame last encoded.
    pub fn nodes(&self) -> &NodeState {
        self.recluster.nodes()
    }

    /// Positions of every node of H_f (global ids) in the frame last encoded: level 0 is that
    /// frame's input, coarser nodes sit at their quadric-optimal positions.
    pub fn node_positions(&self) -> &[Vec3] {
        &self.recluster.nodes().positions
    }

    /// Degeneration node of every triangle in H_f.
    pub fn degeneration(&self) -> &[u32] {
        self.node_of.get_or_init(|| {
            let mut node_of = Vec::new();
            degeneration_nodes(self.recluster.hierarchy(), self.recluster.triangles(), &mut node_of);
            node_of
        })
    }

    /// Level-j ancestors of every triangle's corners, j >= 1 (distinct iff alive at j), as of
    /// the last frame they were followed ([`Encoder::stop_corners`]).
    pub fn corners_at(&self, j: usize) -> &[[u32; 3]] {
        &self.corners[j]
    }

    /// Every level's corners of H_f into `out` (level 0 left empty): level j + 1's are level
    /// j's through the parent map, as [`Hierarchy::all_ancestors`] composes them.
    fn fill_corners(&self, out: &mut Vec<Vec<[u32; 3]>>) {
        let h = self.recluster.hierarchy();
        let tris = self.recluster.triangles();
        out.resize_with(h.levels(), Vec::new);
        out[0].clear();
        for j in 1..h.levels() {
            let (below, above) = out.split_at_mut(j);
            let (prev, next) = (&below[j - 1], &mut above[0]);
            let parent = &h.parent[j - 1];
            next.clear();
            if j == 1 {
                next.extend(tris.iter().map(|t| t.map(|v| parent[v as usize])));
            } else {
                next.extend(prev.iter().map(|c| c.map(|v| parent[v as usize])));
            }
        }
    }

    /// Reclusters for the next frame and returns its delta.
    pub fn encode_frame(&mut self, positions: &[Vec3]) -> (FrameDelta, FrameStats) {
        let mut delta = FrameDelta::default();
        let stats = self.recluster.frame(positions, &mut delta.swaps);
        self.node_of = Default::default();
        if !self.follow_corners {
            return (delta, stats);
        }
        let mut corners = std::mem::take(&mut self.next_corners);
        self.fill_corners(&mut corners);
        for (j, (now, before)) in corners.iter().zip(&self.corners).enumerate().skip(1) {
            for (t, (c, b)) in now.iter().zip(before).enumerate() {
                if c != b && (distinct(*c) || distinct(*b)) {
                    delta.corners.push(CornerUpdate { level: j as u32, t: t as u32, corners: *c });
                }
            }
        }
        self.next_corners = std::mem::replace(&mut self.corners, corners);
        (delta, stats)
    }

    /// The current state as a keyframe.
    pub fn keyframe(&self) -> Keyframe {
        let h = self.recluster.hierarchy();
        let bands = (0..h.levels())
            .map(|j| KeyBand {
                parent: h.parent.get(j).cloned().unwrap_or_default(),
                faces: if j == 0 || !self.follow_corners {
                    Vec::new()
                } else {
                    self.corners[j].iter().enumerate().filter(|(_, c)| distinct(**c)).map(|(t, c)| (t as u32, *c)).collect()
                },
            })
            .collect();
        Keyframe { bands }
    }
}
