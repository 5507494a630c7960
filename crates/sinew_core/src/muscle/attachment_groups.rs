//! A muscle's attachments taken in groups: one per bone (or the world),
//! at the centroid of its held vertices, and the two groups farthest apart
//! — what the muscle's line runs between (`analysis::attachment_span`,
//! [`super::HoldLine`]).

use glam::Vec3;

/// The centroid of `points` per key, keys in the order they first appear.
pub(crate) fn group_centroids<K: PartialEq + Copy>(
    points: impl IntoIterator<Item = (K, Vec3)>,
) -> Vec<(K, Vec3)> {
    let mut groups: Vec<(K, Vec3, f32)> = Vec::new();
    for (key, x) in points {
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => {
                g.1 += x;
                g.2 += 1.0;
            }
            None => groups.push((key, x, 1.0)),
        }
    }
    groups.into_iter().map(|g| (g.0, g.1 / g.2)).collect()
}

/// The two of `points` farthest apart, `(distance, i, j)` with `i < j`
/// (the first such pair on a tie); `None` unless two lie apart.
pub(crate) fn farthest_pair(points: &[Vec3]) -> Option<(f32, usize, usize)> {
    let mut farthest: Option<(f32, usize, usize)> = None;
    for i in 0..points.len() {
        for j in i + 1..points.len() {
            let d = points[i].distance(points[j]);
            if d > 0.0 && farthest.is_none_or(|(best, _, _)| d > best) {
                farthest = Some((d, i, j));
            }
        }
    }
    farthest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_average_their_points_and_the_farthest_pair_is_found() {
        let groups = group_centroids([
            (Some(1), Vec3::ZERO),
            (None, Vec3::X),
            (Some(1), Vec3::new(0.0, 2.0, 0.0)),
            (Some(7), Vec3::new(0.0, 0.0, 3.0)),
        ]);
        let keys: Vec<_> = groups.iter().map(|g| g.0).collect();
        assert_eq!(keys, [Some(1), None, Some(7)]);
        assert_eq!(groups[0].1, Vec3::new(0.0, 1.0, 0.0));
        let points: Vec<Vec3> = groups.iter().map(|g| g.1).collect();
        // Groups 0–2 and 1–2 both lie √10 apart: the first pair is kept.
        let (d, i, j) = farthest_pair(&points).unwrap();
        assert_eq!((i, j), (0, 2));
        assert!((d - 10f32.sqrt()).abs() < 1e-6);
        assert!(farthest_pair(&[Vec3::X, Vec3::X]).is_none());
    }
}
