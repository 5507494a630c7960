//! Moving a surface's vertices smoothly: each round's moves spread over
//! the neighbouring vertices with a falloff ([`spread_moves`]).

use super::PullInside;
use glam::Vec3;

/// Moves vertices by `move_of` (`None`: stays) in rounds until none moves or
/// `options.rounds` are spent, each round's moves spread over the
/// neighbouring vertices with `options.falloff` per pass for
/// `options.spread` passes; only vertices that moved in a round are asked
/// again in the next.
pub(super) fn spread_moves(
    points: &mut [Vec3],
    neighbours: &[Vec<usize>],
    options: &PullInside,
    move_of: impl Fn(Vec3) -> Option<Vec3>,
) {
    spread_rounds(points, neighbours, options, |points, moved| {
        points
            .iter()
            .zip(moved)
            .map(|(&p, &asked)| if asked { move_of(p) } else { None })
            .collect()
    });
}

/// [`spread_moves`] with the moves of a whole round at once: `moves_of`
/// gives each vertex's move (`None`: stays) for the current points and
/// which vertices the last round moved (all, the first time).
pub(super) fn spread_rounds(
    points: &mut [Vec3],
    neighbours: &[Vec<usize>],
    options: &PullInside,
    mut moves_of: impl FnMut(&[Vec3], &[bool]) -> Vec<Option<Vec3>>,
) {
    let n = points.len();
    let mut moved = vec![true; n];
    let mut moves = vec![Vec3::ZERO; n];
    let mut pinned = vec![false; n];
    for _ in 0..options.rounds {
        let asked = moves_of(points, &moved);
        let mut any = false;
        for v in 0..n {
            moves[v] = asked.get(v).copied().flatten().unwrap_or(Vec3::ZERO);
            pinned[v] = moves[v] != Vec3::ZERO;
            any |= pinned[v];
        }
        if !any {
            break;
        }
        let mut next = moves.clone();
        for _ in 0..options.spread {
            for v in 0..n {
                if pinned[v] || neighbours[v].is_empty() {
                    continue;
                }
                let mean = neighbours[v].iter().map(|&u| moves[u]).sum::<Vec3>()
                    / neighbours[v].len() as f32;
                next[v] = options.falloff * mean;
            }
            std::mem::swap(&mut moves, &mut next);
        }
        for v in 0..n {
            moved[v] = moves[v] != Vec3::ZERO;
            points[v] += moves[v];
        }
    }
}

/// Each vertex's neighbours along the triangles' edges.
pub(super) fn vertex_neighbours(n: usize, triangles: &[[u32; 3]]) -> Vec<Vec<usize>> {
    let mut neighbours = vec![Vec::new(); n];
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k] as usize, t[(k + 1) % 3] as usize);
            if a < n && b < n {
                neighbours[a].push(b);
                neighbours[b].push(a);
            }
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
        list.dedup();
    }
    neighbours
}
