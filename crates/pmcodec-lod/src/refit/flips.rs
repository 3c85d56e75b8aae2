//! The one flip repair of the refit's rounds. The collapses check flips in the rest pose only
//! (see `crate::simplify`); a refit round moves vertices (or changes their skins) after the
//! fact, and must not add a flip in any example pose. So after a round, the moves of the corners
//! of every triangle that flips in some pose are stepped back, sweep after sweep, until no
//! triangle does. A triangle whose corners all keep their old state has not flipped, and every
//! kind of move here reaches its old state after a bounded number of steps back, so it ends.

use super::geometry::flipped;
use glam::DVec3;

/// The vertices' moves of one round, between the state before it and the state after it.
pub(super) trait Moves {
    /// Vertex `v` in example pose `k` before the round.
    fn before(&self, v: usize, k: usize) -> DVec3;
    /// Vertex `v` in example pose `k` after the round, with the steps back so far.
    fn after(&self, v: usize, k: usize) -> DVec3;
    /// Steps vertex `v`'s move back in sweep `round` (0 first); false when it has none left.
    fn step_back(&mut self, v: usize, round: usize) -> bool;
    /// Brings what `after` reads up to date after a sweep that stepped something back.
    fn refresh(&mut self) {}
}

/// Steps back the moves of the corners of every triangle of `triangles` that flips in one of
/// `poses` example poses, until none does.
pub(super) fn repair_flips(triangles: &[[u32; 3]], poses: usize, moves: &mut impl Moves) {
    for round in 0.. {
        let mut stepped = false;
        for t in triangles {
            let flips = (0..poses).any(|k| flipped(t.map(|v| moves.before(v as usize, k)), t.map(|v| moves.after(v as usize, k))));
            if flips {
                for &v in t {
                    stepped |= moves.step_back(v as usize, round);
                }
            }
        }
        if !stepped {
            break;
        }
        moves.refresh();
    }
}
