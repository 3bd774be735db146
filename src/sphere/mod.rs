//! Functions and point sets on the sphere (method.md §3-4).
//!
//! - [`srbf`]: the Gaussian spherical radial basis function G(x; λ) = exp(2λ(x − 1)), λ from σ by
//!   the coth relation, its closed-form integral, and the azimuthally averaged ("ring") lobe.
//! - [`lobes`]: the lobe centre layouts ξ_j (hemicube, spherical Fibonacci, isotropic rings) and
//!   their evaluation p(h) = Σ c_j G(h·ξ_j).
//! - [`direction_set`]: the fine, uniform direction set (cube-map texels with exact solid angles).
//! - [`light_tree`]: the direction set arranged as a binary tree, each node with its solid angle,
//!   mean direction and bounding cone.
//! - [`frame`]: local shading frames (n, t, b).
//! - [`hemi_oct`]: the hemi-octahedral map of the hemisphere onto the square (every p(h) table).
//!
//! Inputs: numbers and unit vectors. Outputs: plain data. Invariants: no IO; f64 throughout; local
//! frames are z = normal, x = tangent, y = bitangent = n × t (times the tangent's handedness).

pub mod direction_set;
pub mod frame;
pub mod hemi_oct;
pub mod light_tree;
pub mod lobes;
pub mod srbf;

pub use direction_set::DirectionSet;
pub use frame::Frame;
pub use light_tree::{LightTree, TreeNode};
pub use lobes::{LobeLayout, LobeSet};

/// Errors from sphere parameters that cannot describe a valid lobe or point set.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SphereError {
    /// σ must lie in (0, 1): σ² = 1 − (mean cosine of the lobe) and the mean cosine lies in (0, 1).
    #[error(
        "lobe width sigma = {sigma} is outside (0, 1) radians-equivalent; sigma^2 is 1 minus the lobe's mean cosine"
    )]
    SigmaOutOfRange { sigma: f64 },
    /// λ must be finite and positive.
    #[error("lobe sharpness lambda = {lambda} must be finite and > 0")]
    LambdaOutOfRange { lambda: f64 },
    /// A layout asked for a count it cannot make.
    #[error("lobe layout {layout} cannot have {count} centres: {reason}")]
    BadLayout {
        layout: String,
        count: usize,
        reason: String,
    },
    /// A direction-set resolution out of range.
    #[error("direction set resolution {resolution} per cube face is outside 1..=1024")]
    BadResolution { resolution: usize },
}
