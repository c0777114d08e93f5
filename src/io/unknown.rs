//! Unknown flow vectors in files: the Middlebury marker (a component at or above 1e9, which
//! FlyingThings3D and Sintel use too) and non-finite components; readers turn them into NaN.

/// Components at or above this magnitude mean "unknown" in Middlebury files.
pub const UNKNOWN_THRESHOLD: f32 = 1e9;

/// Whether a vector read from a file means "unknown": a component that is not finite or whose
/// magnitude is at least `1e9` (the Middlebury marker; FlyingThings3D and Sintel use it too).
pub fn is_unknown(u: f32, v: f32) -> bool {
    !(u.abs() < UNKNOWN_THRESHOLD && v.abs() < UNKNOWN_THRESHOLD)
}

/// Sets both components of every unknown vector ([`is_unknown`]) to NaN in planar flow data
/// `[u plane, v plane]`.
pub(crate) fn unknown_to_nan(data: &mut [f32]) {
    let n = data.len() / 2;
    let (u, v) = data.split_at_mut(n);
    for (a, b) in u.iter_mut().zip(v.iter_mut()) {
        if is_unknown(*a, *b) {
            *a = f32::NAN;
            *b = f32::NAN;
        }
    }
}
