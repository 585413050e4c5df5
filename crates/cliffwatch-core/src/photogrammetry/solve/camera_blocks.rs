//! The image and interior part U of the normal equations, accumulated block by block: U couples no
//! two images, so it is held as one 6 × 6 block per image, that image's coupling with its camera's
//! free interior parameters, and one interior block per camera — O(images) numbers instead of a
//! dense matrix of all camera unknowns per thread, written into the dense U once per build.

use faer::Mat;

/// Index of element (a, b), a ≥ b, of a lower triangle packed row by row.
#[inline(always)]
fn tri(a: usize, b: usize) -> usize {
    a * (a + 1) / 2 + b
}

/// Partial sums of U and b_c over some observations.
#[derive(Debug, Clone)]
pub struct CameraBlocks {
    /// Per image, the lower triangle of its 6 × 6 block (packed row by row).
    image: Vec<[f64; 21]>,
    /// Per image, its coupling with its camera's free interior parameters: row l (interior lane l
    /// of the camera) holds 6 numbers, one per image unknown; `image_interior_at[j]` is the start.
    image_interior: Vec<f64>,
    image_interior_at: Vec<usize>,
    /// Per camera, the lower triangle of its interior block (packed row by row), from
    /// `interior_at[cam]`.
    interior: Vec<f64>,
    interior_at: Vec<usize>,
    /// Right-hand side b_c (all camera unknowns).
    pub bc: Vec<f64>,
}

impl CameraBlocks {
    /// Zero blocks for images with cameras `image_camera` and `interior_count[cam]` free interior
    /// parameters per camera; `nc` camera unknowns in all.
    pub fn new(image_camera: &[usize], interior_count: &[usize], nc: usize) -> Self {
        let mut image_interior_at = Vec::with_capacity(image_camera.len());
        let mut next = 0;
        for &cam in image_camera {
            image_interior_at.push(next);
            next += 6 * interior_count[cam];
        }
        let mut interior_at = Vec::with_capacity(interior_count.len());
        let mut total = 0;
        for &ni in interior_count {
            interior_at.push(total);
            total += ni * (ni + 1) / 2;
        }
        CameraBlocks {
            image: vec![[0.0; 21]; image_camera.len()],
            image_interior: vec![0.0; next],
            image_interior_at,
            interior: vec![0.0; total],
            interior_at,
            bc: vec![0.0; nc],
        }
    }

    /// Adds one observation's local lower triangle `jtj` of JᵀPJ and its JᵀPe `jte` (local columns:
    /// image `image`'s six unknowns, then its camera `cam`'s interior lanes at global columns
    /// `cols[6..]`; N ≥ `cols.len()`, entries beyond are ignored).
    #[inline(always)]
    pub fn add<const N: usize>(
        &mut self,
        image: usize,
        cam: usize,
        jtj: &[[f64; N]; N],
        jte: &[f64; N],
        cols: &[(usize, usize)],
    ) {
        let block = &mut self.image[image];
        for a in 0..6 {
            for b in 0..=a {
                block[tri(a, b)] += jtj[a][b];
            }
        }
        let ni = cols.len() - 6;
        if ni > 0 {
            let at = self.image_interior_at[image];
            let coupling = &mut self.image_interior[at..at + 6 * ni];
            for l in 0..ni {
                for b in 0..6 {
                    coupling[6 * l + b] += jtj[6 + l][b];
                }
            }
            let at = self.interior_at[cam];
            for l in 0..ni {
                for m in 0..=l {
                    self.interior[at + tri(l, m)] += jtj[6 + l][6 + m];
                }
            }
        }
        for (a, &(g, _)) in cols.iter().enumerate() {
            self.bc[g] -= jte[a];
        }
    }

    /// Adds the partial sums of `other` (same network).
    pub fn merge(mut self, other: CameraBlocks) -> CameraBlocks {
        for (a, b) in self.image.iter_mut().zip(&other.image) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        for (x, y) in self.image_interior.iter_mut().zip(&other.image_interior) {
            *x += y;
        }
        for (x, y) in self.interior.iter_mut().zip(&other.interior) {
            *x += y;
        }
        for (x, y) in self.bc.iter_mut().zip(&other.bc) {
            *x += y;
        }
        self
    }

    /// Writes the blocks into the dense, symmetric U (`u`: zeroed here, resized to nc × nc);
    /// `interior_columns[cam]` are the global columns of camera cam's interior lanes.
    pub fn write(&self, u: &mut Mat<f64>, image_camera: &[usize], interior_columns: &[Vec<usize>]) {
        let nc = self.bc.len();
        if u.nrows() == nc && u.ncols() == nc {
            u.fill(0.0);
        } else {
            *u = Mat::zeros(nc, nc);
        }
        let mut set = |r: usize, c: usize, x: f64| {
            u[(r, c)] = x;
            u[(c, r)] = x;
        };
        for (j, block) in self.image.iter().enumerate() {
            for a in 0..6 {
                for b in 0..=a {
                    set(6 * j + a, 6 * j + b, block[tri(a, b)]);
                }
            }
            let cols = &interior_columns[image_camera[j]];
            let at = self.image_interior_at[j];
            for (l, &g) in cols.iter().enumerate() {
                for b in 0..6 {
                    set(g, 6 * j + b, self.image_interior[at + 6 * l + b]);
                }
            }
        }
        for (cam, cols) in interior_columns.iter().enumerate() {
            let at = self.interior_at[cam];
            for (l, &gl) in cols.iter().enumerate() {
                for (m, &gm) in cols.iter().enumerate().take(l + 1) {
                    set(gl, gm, self.interior[at + tri(l, m)]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The blocks written into U equal the dense sum of the same observations' terms.
    #[test]
    fn blocks_equal_the_dense_sum() {
        // Two cameras (2 and 1 free interior parameters), three images.
        let image_camera = [0, 1, 0];
        let interior_columns = vec![vec![18, 19], vec![20]];
        let nc = 21;
        let mut blocks = CameraBlocks::new(&image_camera, &[2, 1], nc);
        let mut dense = Mat::<f64>::zeros(nc, nc);
        let mut bc = vec![0.0; nc];
        for k in 0..7usize {
            let image = k % 3;
            let cam = image_camera[image];
            let mut cols: Vec<(usize, usize)> = (0..6).map(|a| (6 * image + a, a)).collect();
            cols.extend(interior_columns[cam].iter().map(|&g| (g, 0)));
            let n = cols.len();
            let d: Vec<f64> = (0..n)
                .map(|a| ((a + 1) * (k + 2)) as f64 * 0.1 - 0.3)
                .collect();
            let mut jtj = [[0.0; 14]; 14];
            let mut jte = [0.0; 14];
            for a in 0..n {
                jte[a] = d[a] * 0.5;
                bc[cols[a].0] -= jte[a];
                for b in 0..=a {
                    jtj[a][b] = d[a] * d[b];
                    dense[(cols[a].0, cols[b].0)] += d[a] * d[b];
                    if a != b {
                        dense[(cols[b].0, cols[a].0)] += d[a] * d[b];
                    }
                }
            }
            let mut half = CameraBlocks::new(&image_camera, &[2, 1], nc);
            half.add(image, cam, &jtj, &jte, &cols);
            blocks = blocks.merge(half);
        }
        let mut u = Mat::zeros(0, 0);
        blocks.write(&mut u, &image_camera, &interior_columns);
        for r in 0..nc {
            assert!((blocks.bc[r] - bc[r]).abs() < 1e-12);
            for c in 0..nc {
                assert!(
                    (u[(r, c)] - dense[(r, c)]).abs() < 1e-12,
                    "({r},{c}): {} vs {}",
                    u[(r, c)],
                    dense[(r, c)]
                );
            }
        }
    }
}
