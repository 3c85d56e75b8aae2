//! A glTF animation's frames made one at a time: a skinned character of 34,159 vertices
//! animated for 35 s at 30 frames per second is 430 MB of positions held at once, and a
//! streaming encoder needs only the frame it reclusters (issue 17, "Encode cost").

use super::*;

/// The frames of one animation of a [`RiggedMesh`] at one frame rate, each posed from the
/// skeleton, the morph weights and the node transforms when it is asked for. Made by
/// [`RiggedMesh::sampler`]; [`FrameSampler::frame`] is bit for bit the frame
/// [`RiggedMesh::to_sequence_with`] holds (that function is this one, collected).
#[derive(Clone, Debug)]
pub struct FrameSampler<'a> {
    pub(super) rig: &'a RiggedMesh,
    pub(super) animation: Option<&'a Animation>,
    pub(super) frame_rate: f32,
    pub(super) count: usize,
    pub(super) label: String,
}

impl<'a> FrameSampler<'a> {
    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.count
    }

    /// Time of frame `i` in seconds.
    pub fn time(&self, i: usize) -> f32 {
        i as f32 / self.frame_rate
    }

    /// Frame `i`'s name, as the sequence's `frame_names` has it.
    pub fn name(&self, i: usize) -> String {
        format!("{}@{:.3}s", self.label, self.time(i))
    }

    /// Frame `i`'s positions (frames past the last are posed at their time all the same, as
    /// the animation clamps).
    pub fn frame(&self, i: usize) -> Vec<Vec3> {
        self.rig.pose(self.animation, self.time(i))
    }

    /// Frames `from..`, each made when the iterator is advanced.
    pub fn frames(&self, from: usize) -> impl Iterator<Item = Vec<Vec3>> + Send + 'a {
        let (rig, animation, rate) = (self.rig, self.animation, self.frame_rate);
        (from..self.count).map(move |i| rig.pose(animation, i as f32 / rate))
    }

    /// What a sequence holds besides its frames (triangles, sources, morph displacement, the
    /// skin with every frame's matrices, appearance, every frame's name), with frame 0 only:
    /// the head an encoder streams the other frames after. Validated as a one-frame sequence.
    pub fn head(&self) -> Result<Sequence, MeshError> {
        let seq = self.head_unchecked();
        seq.validate()?;
        Ok(seq)
    }

    pub(super) fn head_unchecked(&self) -> Sequence {
        let rig = self.rig;
        let times: Vec<f32> = (0..self.count).map(|i| self.time(i)).collect();
        Sequence {
            triangles: rig.triangles.clone(),
            frames: vec![self.frame(0)],
            frame_rate: self.frame_rate,
            source: rig.source.clone(),
            morph_displacement: rig.morph_displacement(),
            frame_names: (0..self.count).map(|i| self.name(i)).collect(),
            appearance: rig.appearance.clone(),
            skin: crate::skin::sequence_skin(rig, self.animation, &times),
        }
    }

    /// Every frame posed once and dropped: their bounding box (as [`Sequence::bounds`] gives it), so that an encoder can fix its
    /// quantization grid before the first frame is coded without holding the frames. Checks
    /// what [`Sequence::validate`] checks of frames (every position finite), naming the frame.
    /// Costs one posing of every frame (a tenth or less of reclustering them).
    pub fn bounds(&self) -> Result<(Vec3, Vec3), MeshError> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        let mut frame = Vec::new();
        for i in 0..self.count {
            self.rig.pose_into(self.animation, self.time(i), &mut frame);
            for (v, p) in frame.iter().enumerate() {
                if !p.is_finite() {
                    return Err(MeshError::NonFinite { frame: format!("{i} ({})", self.name(i)), vertex: v as u32 });
                }
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
        }
        if self.rig.vertex_count() == 0 {
            return Err(MeshError::Empty { what: "no vertices".into() });
        }
        Ok((lo, hi))
    }
}
