//! Optimal assignment (the Hungarian method, O(n³) with potentials) for matching detections to
//! tracks by distance; costs above a gate are forbidden.

/// Minimum-cost assignment of rows to columns of `cost` (rows × cols, any shape). Returns for
/// each row the assigned column, or `None`. Entries that are not finite are forbidden pairs.
pub fn assign(cost: &[Vec<f64>]) -> Vec<Option<usize>> {
    let n = cost.len();
    if n == 0 {
        return Vec::new();
    }
    let m = cost[0].len();
    if m == 0 {
        return vec![None; n];
    }
    // Square it with a large finite cost for forbidden and dummy pairs.
    let big = cost
        .iter()
        .flatten()
        .filter(|v| v.is_finite())
        .fold(0.0f64, |a, &b| a.max(b.abs()))
        * 4.0
        + 1e6;
    let k = n.max(m);
    let c = |i: usize, j: usize| -> f64 {
        if i < n && j < m && cost[i][j].is_finite() {
            cost[i][j]
        } else {
            big
        }
    };
    // Jonker–Volgenant style shortest augmenting paths with row/column potentials (1-based).
    let (mut u, mut v) = (vec![0.0; k + 1], vec![0.0; k + 1]);
    let (mut p, mut way) = (vec![0usize; k + 1], vec![0usize; k + 1]);
    for i in 1..=k {
        p[0] = i;
        let mut j0 = 0;
        let mut minv = vec![f64::INFINITY; k + 1];
        let mut used = vec![false; k + 1];
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = f64::INFINITY;
            let mut j1 = 0;
            for j in 1..=k {
                if !used[j] {
                    let cur = c(i0 - 1, j - 1) - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            for j in 0..=k {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut out = vec![None; n];
    for j in 1..=k {
        let i = p[j];
        if i >= 1 && i <= n && j <= m && cost[i - 1][j - 1].is_finite() {
            out[i - 1] = Some(j - 1);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn optimal_not_greedy_and_gated() {
        // Greedy would take (0,0)=1 and then (1,1)=10; optimal is 2 + 3.
        let cost = vec![vec![1.0, 2.0], vec![3.0, 10.0]];
        assert_eq!(assign(&cost), vec![Some(1), Some(0)]);
        // Rectangular, with a forbidden pair.
        let cost = vec![
            vec![f64::INFINITY, 5.0, 1.0],
            vec![2.0, f64::INFINITY, f64::INFINITY],
        ];
        assert_eq!(assign(&cost), vec![Some(2), Some(0)]);
        // More rows than columns: one row stays unassigned.
        let cost = vec![vec![1.0], vec![0.5], vec![f64::INFINITY]];
        assert_eq!(assign(&cost), vec![None, Some(0), None]);
        assert!(assign(&[]).is_empty());
    }
}
