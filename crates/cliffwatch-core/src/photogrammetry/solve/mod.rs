//! Solving the normal equations: [`normals`] forms them and reduces them by the Schur complement
//! over the 3 × 3 point blocks ([`normal_equations`] holds them, [`camera_blocks`] the interior
//! blocks, [`dense`] and [`dense_schur`] the dense kernels), and [`lm`] iterates
//! Levenberg–Marquardt on them.

pub(crate) mod camera_blocks;
pub(crate) mod dense;
pub(crate) mod dense_schur;
pub(crate) mod lm;
pub(crate) mod normal_equations;
pub(crate) mod normals;
