//! Distributions on the plane that the samplers are built from: axis-aligned Gaussians and
//! Box–Muller ([`gaussian`], paper Eq. 1–3), monotonic rational-quadratic splines
//! ([`spline`], Eq. 4) and tabulated piecewise-constant 2-D distributions ([`table2d`],
//! Eq. 5–6).

pub mod gaussian;
pub mod spline;
pub mod table2d;

pub use table2d::Table2D;
