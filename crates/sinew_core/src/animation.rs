//! Keyframed scalar curves (activation) and rigid transform tracks (bones).

use glam::{Affine3A, Quat, Vec3};
use serde::{Deserialize, Serialize};

/// Interpolation between keys.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Interpolation {
    /// Hold the previous key.
    Step,
    /// Linear.
    #[default]
    Linear,
    /// Smoothstep ease-in/ease-out between keys.
    Smooth,
}

impl Interpolation {
    fn shape(self, t: f32) -> f32 {
        match self {
            Self::Step => 0.0,
            Self::Linear => t,
            Self::Smooth => t * t * (3.0 - 2.0 * t),
        }
    }
}

/// Finds the key interval of `time`: `(i, j, t)` with keys i, j and fraction t.
/// `time_at(k)` is the time of key `k`; keys are sorted. No allocation.
fn locate(n: usize, time_at: impl Fn(usize) -> f32, time: f32) -> (usize, usize, f32) {
    if n == 0 || time <= time_at(0) {
        return (0, 0, 0.0);
    }
    if time >= time_at(n - 1) {
        return (n - 1, n - 1, 0.0);
    }
    let (mut lo, mut hi) = (0, n - 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if time_at(mid) <= time {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let span = time_at(hi) - time_at(lo);
    let t = if span > 0.0 {
        (time - time_at(lo)) / span
    } else {
        1.0
    };
    (lo, hi, t)
}

/// A scalar curve of `(time s, value)` keys, held constant outside its range.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Curve {
    /// Keys sorted by time. Units: seconds.
    pub keys: Vec<(f32, f32)>,
    /// Interpolation. Default: linear.
    #[serde(default)]
    pub interpolation: Interpolation,
}

impl Curve {
    /// A constant curve.
    pub fn constant(value: f32) -> Self {
        Self {
            keys: vec![(0.0, value)],
            interpolation: Interpolation::Linear,
        }
    }

    /// Value at `time` (0 for an empty curve).
    pub fn sample(&self, time: f32) -> f32 {
        if self.keys.is_empty() {
            return 0.0;
        }
        let (i, j, t) = locate(self.keys.len(), |k| self.keys[k].0, time);
        let (a, b) = (self.keys[i].1, self.keys[j].1);
        a + (b - a) * self.interpolation.shape(t)
    }

    /// Checks the keys: at least one, times finite and strictly increasing,
    /// values finite and within `range`. The error names the key.
    pub fn validate(&self, range: std::ops::RangeInclusive<f32>) -> Result<(), String> {
        if self.keys.is_empty() {
            return Err("the curve has no keys (give at least one, or none for no curve)".into());
        }
        check_times(self.keys.iter().map(|k| k.0))?;
        for (i, &(time, value)) in self.keys.iter().enumerate() {
            if !value.is_finite() || !range.contains(&value) {
                return Err(format!(
                    "key {i} (time {time} s) has value {value}, expected a finite value in [{}, {}]",
                    range.start(),
                    range.end()
                ));
            }
        }
        Ok(())
    }
}

/// Key times must be finite and strictly increasing (a duplicated time is
/// ambiguous: which value holds at it?).
fn check_times(times: impl Iterator<Item = f32>) -> Result<(), String> {
    let mut previous = f32::NEG_INFINITY;
    for (i, time) in times.enumerate() {
        if !time.is_finite() {
            return Err(format!("key {i} has time {time}, expected a finite time"));
        }
        if time <= previous {
            return Err(format!(
                "key {i} has time {time} s, not after key {}'s {previous} s (keys must be sorted by time, without repeats)",
                i - 1
            ));
        }
        previous = time;
    }
    Ok(())
}

/// One rigid pose key.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformKey {
    /// Time. Units: s.
    pub time: f32,
    /// Translation. Units: m.
    pub translation: Vec3,
    /// Rotation (unit quaternion, `x, y, z, w`).
    #[serde(default = "identity_quat")]
    pub rotation: Quat,
}

fn identity_quat() -> Quat {
    Quat::IDENTITY
}

/// A keyframed rigid transform (translation + rotation).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformTrack {
    /// Keys sorted by time.
    pub keys: Vec<TransformKey>,
    /// Interpolation. Default: linear (slerp for rotation).
    #[serde(default)]
    pub interpolation: Interpolation,
}

impl TransformTrack {
    /// Pose at `time` (identity for an empty track).
    pub fn sample(&self, time: f32) -> Affine3A {
        let (rotation, translation) = self.sample_parts(time);
        Affine3A::from_rotation_translation(rotation, translation)
    }

    /// Rotation and translation at `time` (identity for an empty track): what
    /// [`TransformTrack::sample`] composes, for hosts that keep a rotation and
    /// a translation (a Bevy `Transform` composes them to the same bits).
    pub fn sample_parts(&self, time: f32) -> (Quat, Vec3) {
        if self.keys.is_empty() {
            return (Quat::IDENTITY, Vec3::ZERO);
        }
        let (i, j, t) = locate(self.keys.len(), |k| self.keys[k].time, time);
        let s = self.interpolation.shape(t);
        let (a, b) = (&self.keys[i], &self.keys[j]);
        (
            a.rotation.normalize().slerp(b.rotation.normalize(), s),
            a.translation.lerp(b.translation, s),
        )
    }

    /// Checks the keys: times finite and strictly increasing, translations
    /// finite, rotations finite and of non-zero length (they are normalised
    /// when sampled). An empty track is valid (identity). The error names
    /// the key.
    pub fn validate(&self) -> Result<(), String> {
        check_times(self.keys.iter().map(|k| k.time))?;
        for (i, k) in self.keys.iter().enumerate() {
            if !k.translation.is_finite() {
                return Err(format!(
                    "key {i} (time {} s) has translation {}, expected finite coordinates",
                    k.time, k.translation
                ));
            }
            let length = k.rotation.length();
            if !(length.is_finite() && length > 1e-6) {
                return Err(format!(
                    "key {i} (time {} s) has rotation {} of length {length}, expected a unit quaternion",
                    k.time, k.rotation
                ));
            }
        }
        Ok(())
    }
}

/// Interpolates two rigid transforms (slerp + lerp), as substeps do within a frame.
pub fn interpolate_rigid(a: Affine3A, b: Affine3A, t: f32) -> Affine3A {
    if t >= 1.0 {
        return b;
    }
    let (sa, ra, ta) = a.to_scale_rotation_translation();
    let (sb, rb, tb) = b.to_scale_rotation_translation();
    Affine3A::from_scale_rotation_translation(sa.lerp(sb, t), ra.slerp(rb, t), ta.lerp(tb, t))
}
