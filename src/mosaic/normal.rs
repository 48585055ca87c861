//! The normal equations AᵀA x = Aᵀb of the balance's least squares, filled
//! one weighted row of A (or one pair of images' block) at a time. Each
//! image's unknowns meet only those of the images it overlaps, so AᵀA is
//! kept sparse: a block of thousands of images takes a few MB, where a
//! dense matrix would take gigabytes. Small systems (most blocks) are
//! solved by a dense Cholesky factorization; larger ones by conjugate
//! gradients preconditioned by the diagonal (nalgebra-sparse's Cholesky
//! does no fill-reducing ordering, and its authors advise against it).

use nalgebra::{DMatrix, DVector};
use std::collections::BTreeMap;

/// Up to this many unknowns, the dense factorization (8 MB).
const DENSE_UP_TO: usize = 1024;

pub struct Normal {
    ata: BTreeMap<(usize, usize), f64>,
    atb: Vec<f64>,
}

impl Normal {
    pub fn new(unknowns: usize) -> Normal {
        Normal { ata: BTreeMap::new(), atb: vec![0.0; unknowns] }
    }

    /// The row (unknown, coefficient)…, its right-hand side and weight.
    pub fn add(&mut self, row: &[(usize, f64)], rhs: f64, w: f64) {
        for &(p, u) in row {
            self.atb[p] += w * u * rhs;
            for &(q, v) in row {
                *self.ata.entry((p, q)).or_insert(0.0) += w * u * v;
            }
        }
    }

    /// A block already summed over many rows: `ata` and `atb` of the
    /// unknowns `at` (in that order).
    pub fn add_block(&mut self, at: &[usize], ata: &DMatrix<f64>, atb: &DVector<f64>) {
        for (a, &p) in at.iter().enumerate() {
            self.atb[p] += atb[a];
            for (b, &q) in at.iter().enumerate() {
                *self.ata.entry((p, q)).or_insert(0.0) += ata[(a, b)];
            }
        }
    }

    /// The least-squares solution; `None` where the system is singular.
    pub fn solve(self) -> Option<Vec<f64>> {
        if self.atb.len() <= DENSE_UP_TO {
            self.solve_dense()
        } else {
            self.solve_sparse()
        }
    }

    fn solve_dense(self) -> Option<Vec<f64>> {
        let n = self.atb.len();
        let mut ata = DMatrix::zeros(n, n);
        for (&(p, q), &v) in &self.ata {
            ata[(p, q)] = v;
        }
        let atb = DVector::from_vec(self.atb);
        ata.cholesky().map(|c| c.solve(&atb).iter().copied().collect())
    }

    fn solve_sparse(self) -> Option<Vec<f64>> {
        let n = self.atb.len();
        // Rows in order (the map is sorted by row, then column).
        let mut start = vec![0usize; n + 1];
        let (mut cols, mut vals) = (Vec::with_capacity(self.ata.len()), Vec::with_capacity(self.ata.len()));
        let mut diag = vec![0.0; n];
        for (&(p, q), &v) in &self.ata {
            start[p + 1] += 1;
            cols.push(q);
            vals.push(v);
            if p == q {
                diag[p] = v;
            }
        }
        for p in 0..n {
            start[p + 1] += start[p];
        }
        if diag.iter().any(|&d| !(d > 0.0)) {
            return None;
        }
        let times = |x: &[f64], y: &mut [f64]| {
            for (p, out) in y.iter_mut().enumerate() {
                *out = (start[p]..start[p + 1]).map(|k| vals[k] * x[cols[k]]).sum();
            }
        };
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let b = self.atb;
        let bb = dot(&b, &b);
        let mut x = vec![0.0; n];
        if bb == 0.0 {
            return Some(x);
        }
        let mut r = b.clone();
        let mut z: Vec<f64> = r.iter().zip(&diag).map(|(r, d)| r / d).collect();
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let mut ap = vec![0.0; n];
        for _ in 0..20 * n {
            times(&p, &mut ap);
            let pap = dot(&p, &ap);
            if !(pap > 0.0) {
                return None;
            }
            let alpha = rz / pap;
            for k in 0..n {
                x[k] += alpha * p[k];
                r[k] -= alpha * ap[k];
            }
            // Converged well past what a gain or an offset shows.
            if dot(&r, &r) <= 1e-26 * bb {
                return Some(x);
            }
            for k in 0..n {
                z[k] = r[k] / diag[k];
            }
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for k in 0..n {
                p[k] = z[k] + beta * p[k];
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of 600 "images" (1200 unknowns), each
    /// pair of neighbours asking that their values agree, each pulled
    /// weakly to its own level: conjugate gradients give what the dense
    /// factorization gives, and a sparse store of a few entries a row.
    #[test]
    fn sparse_and_dense_solutions_agree() {
        let images = 600;
        let fill = |n: &mut Normal| {
            for i in 0..images - 1 {
                let (a, b) = (1.0 + (i % 7) as f64 * 0.05, 1.0 + ((i + 1) % 5) as f64 * 0.04);
                n.add(&[(2 * i, a), (2 * i + 1, 1.0), (2 * i + 2, -b), (2 * i + 3, -1.0)], 0.0, 1.0);
                n.add(&[(2 * i, a * 0.3), (2 * i + 2, -b * 0.3)], 0.0, 1.0);
            }
            for i in 0..images {
                n.add(&[(2 * i, 1.0)], 1.0, 0.01);
                n.add(&[(2 * i + 1, 1.0)], 0.02 * (i % 3) as f64, 0.01);
            }
        };
        let mut sparse = Normal::new(2 * images);
        fill(&mut sparse);
        assert!(sparse.ata.len() < 6 * 2 * images, "{} entries", sparse.ata.len());
        let mut dense = Normal::new(2 * images);
        fill(&mut dense);
        let (s, d) = (sparse.solve_sparse().expect("converges"), dense.solve_dense().expect("positive definite"));
        let worst = s.iter().zip(&d).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-9, "largest difference {worst:e}");
        assert!(d.iter().any(|v| (v - 1.0).abs() > 1e-3 && v.abs() > 1e-3), "a trivial solution would prove nothing");
    }

    /// A block summed apart equals its rows added one by one.
    #[test]
    fn a_block_adds_as_its_rows() {
        let rows = [([(0usize, 1.5), (1, -2.0)], 0.5, 2.0), ([(0, 0.25), (1, 1.0)], -1.0, 1.0)];
        let mut by_rows = Normal::new(4);
        let mut by_block = Normal::new(4);
        let (mut ata, mut atb) = (DMatrix::zeros(2, 2), DVector::zeros(2));
        for (row, rhs, w) in rows {
            let row = row.map(|(k, v)| (k + 2, v));
            by_rows.add(&row, rhs, w);
            for (a, &(_, u)) in row.iter().enumerate() {
                atb[a] += w * u * rhs;
                for (b, &(_, v)) in row.iter().enumerate() {
                    ata[(a, b)] += w * u * v;
                }
            }
        }
        by_block.add_block(&[2, 3], &ata, &atb);
        assert_eq!(by_rows.ata, by_block.ata);
        assert_eq!(by_rows.atb, by_block.atb);
    }
}
