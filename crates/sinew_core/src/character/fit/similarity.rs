//! Least-squares similarity between matched point sets.

use super::Similarity;
use glam::{Quat, Vec3};

/// The similarity that maps `from` onto `to` best in the least-squares
/// sense (Horn's quaternion method; two points: the shortest turn between
/// them, which leaves the roll about their line alone). `None` when the
/// points of `from` coincide.
pub fn least_squares_similarity(from: &[Vec3], to: &[Vec3]) -> Option<Similarity> {
    let n = from.len() as f32;
    let (a_mean, c_mean) = (from.iter().sum::<Vec3>() / n, to.iter().sum::<Vec3>() / n);
    let a: Vec<Vec3> = from.iter().map(|&p| p - a_mean).collect();
    let c: Vec<Vec3> = to.iter().map(|&p| p - c_mean).collect();
    let spread: f32 = a.iter().map(|p| p.length_squared()).sum();
    if spread < 1e-12 {
        return None;
    }
    let rotation = if from.len() == 2 {
        let (u, v) = (a[1] - a[0], c[1] - c[0]);
        if v.length() < 1e-9 {
            Quat::IDENTITY
        } else {
            Quat::from_rotation_arc(u.normalize(), v.normalize())
        }
    } else {
        horn_rotation(&a, &c)
    };
    let scale = a
        .iter()
        .zip(&c)
        .map(|(&p, &q)| q.dot(rotation * p))
        .sum::<f32>()
        / spread;
    Some(Similarity {
        scale,
        rotation,
        translation: c_mean - scale * (rotation * a_mean),
    })
}

/// The rotation that best turns the centred points `a` onto `c`: the
/// eigenvector of the largest eigenvalue of Horn's 4 × 4 matrix.
fn horn_rotation(a: &[Vec3], c: &[Vec3]) -> Quat {
    let mut s = [[0.0f64; 3]; 3];
    for (p, q) in a.iter().zip(c) {
        for (i, pi) in p.to_array().into_iter().enumerate() {
            for (j, qj) in q.to_array().into_iter().enumerate() {
                s[i][j] += pi as f64 * qj as f64;
            }
        }
    }
    let [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = s;
    let mut m = [
        [xx + yy + zz, yz - zy, zx - xz, xy - yx],
        [yz - zy, xx - yy - zz, xy + yx, zx + xz],
        [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
        [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
    ];
    // Cyclic Jacobi sweeps: m → diagonal, v → eigenvectors (columns).
    let mut v = [[0.0f64; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..32 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| m[i][j] * m[i][j])
            .sum();
        if off < 1e-24 {
            break;
        }
        for p in 0..4 {
            for q in p + 1..4 {
                if m[p][q].abs() < 1e-30 {
                    continue;
                }
                let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let (cos, sin) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
                for row in &mut m {
                    let (mkp, mkq) = (row[p], row[q]);
                    row[p] = cos * mkp - sin * mkq;
                    row[q] = sin * mkp + cos * mkq;
                }
                let (row_p, row_q) = (m[p], m[q]);
                for k in 0..4 {
                    m[p][k] = cos * row_p[k] - sin * row_q[k];
                    m[q][k] = sin * row_p[k] + cos * row_q[k];
                }
                for row in &mut v {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = cos * vp - sin * vq;
                    row[q] = sin * vp + cos * vq;
                }
            }
        }
    }
    let best = (0..4)
        .max_by(|&i, &j| m[i][i].total_cmp(&m[j][j]))
        .unwrap_or(0);
    let (w, x, y, z) = (v[0][best], v[1][best], v[2][best], v[3][best]);
    Quat::from_xyzw(x as f32, y as f32, z as f32, w as f32).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::character::fit::Similarity;

    #[test]
    fn least_squares_recovers_a_similarity() {
        let truth = Similarity {
            scale: 1.3,
            rotation: Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 0.9),
            translation: Vec3::new(0.1, -0.4, 0.25),
        };
        let from = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.3, 0.1, 0.0),
            Vec3::new(-0.1, 0.4, 0.2),
            Vec3::new(0.2, -0.2, 0.5),
        ];
        let to: Vec<Vec3> = from.iter().map(|&p| truth.apply(p)).collect();
        let fit = least_squares_similarity(&from, &to).unwrap();
        assert!((fit.scale - truth.scale).abs() < 1e-4, "{fit:?}");
        assert!(fit.rotation.angle_between(truth.rotation) < 1e-3, "{fit:?}");
        assert!(
            fit.translation.distance(truth.translation) < 1e-4,
            "{fit:?}"
        );
        // Two points: exact ends, shortest turn.
        let fit = least_squares_similarity(&from[..2], &to[..2]).unwrap();
        for (p, q) in from[..2].iter().zip(&to[..2]) {
            assert!(fit.apply(*p).distance(*q) < 1e-5);
        }
        assert!(least_squares_similarity(&[Vec3::ONE; 3], &to[..3]).is_none());
    }
}
