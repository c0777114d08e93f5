//! The thread pool of the host kernels (rayon): two tasks side by side, and element-wise maps
//! over a slice in parallel chunks. The only rayon entry points outside the kernels' own loops.

use rayon::prelude::*;

/// Values per parallel task of the element-wise maps: a layer's output is up to 2²¹ values (the
/// encoders' first stage), the update block's a few 10⁴.
const CHUNK: usize = 1 << 14;

/// `(a(), b())`, run side by side on the thread pool.
pub fn join<A: Send, B: Send>(
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    rayon::join(a, b)
}

/// `y ← f(y)`, in parallel chunks.
pub fn map(y: &mut [f32], f: impl Fn(f32) -> f32 + Sync) {
    y.par_chunks_mut(CHUNK)
        .for_each(|c| c.iter_mut().for_each(|v| *v = f(*v)));
}

/// `f(y, g)` element-wise, in parallel chunks.
pub fn zip_map(y: &[f32], g: &[f32], f: impl Fn(f32, f32) -> f32 + Sync) -> Vec<f32> {
    let mut out = vec![0f32; g.len()];
    out.par_chunks_mut(CHUNK)
        .zip(y.par_chunks(CHUNK).zip(g.par_chunks(CHUNK)))
        .for_each(|(o, (y, g))| {
            for ((o, &y), &g) in o.iter_mut().zip(y).zip(g) {
                *o = f(y, g);
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Chunked maps cover every element, across chunk boundaries and for empty slices.
    #[test]
    fn maps_cover_every_element() {
        for n in [0, 1, CHUNK - 1, CHUNK, 3 * CHUNK + 5] {
            let mut y: Vec<f32> = (0..n).map(|i| i as f32).collect();
            map(&mut y, |v| v + 1.0);
            assert!(y.iter().enumerate().all(|(i, &v)| v == i as f32 + 1.0));
            let z = zip_map(&y, &y, |a, b| a * b);
            assert!(z.iter().zip(&y).all(|(&z, &y)| z == y * y));
        }
        assert_eq!(join(|| 1, || 2), (1, 2));
    }
}
