//! Distributions on the plane that the samplers are built from: axis-aligned Gaussians and
//! Box–Muller ([`gaussian`], paper Eq. 1–3), monotonic rational-quadratic splines
//! ([`spline`], Eq. 4), tabulated piecewise-constant 2-D distributions ([`table2d`],
//! Eq. 5–6) and the piecewise-bilinear warps of measured materials ([`marginal2d`]).

pub mod gaussian;
pub mod marginal2d;
pub mod spline;
pub mod table2d;

pub use marginal2d::Marginal2D;
pub use table2d::Table2D;
