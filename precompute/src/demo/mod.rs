//! The main job (`neusample demo`) and the fixture generator (`neusample fixtures`).
//!
//! The demo trains every method on the default materials (or loads the committed fixture
//! blobs), bakes and verifies each blob, and evaluates it through the runtime's public API:
//!
//! 1. **pdf fit** ([`crate::eval::fit()`]): KL(p* ‖ p) and pdf MSE over random conditions,
//!    and a Fig. 7-style grid of p* beside every method's p for a few conditions;
//! 2. **cost** ([`crate::eval::cost()`]): single-thread ns of prepare / sample / pdf, and the
//!    Table 1 ratio to the material's own evaluation;
//! 3. **rendering** (`neusample_render`, [`crate::eval::metrics`]): a patch and a sphere
//!    under a sky with a small bright sun, rendered with every method plus the tabulated
//!    oracle; MSE against a high-sample reference at equal spp and at equal time,
//!    convergence plots (Fig. 8), equal-time images (Figs. 1, 9) and the Table 2 speed-up
//!    over the improved baseline.
//!
//! It writes `report.md`, `report.json` (schema in `docs/report_schema.md` and [`Report`]), `images/`,
//! `plots/` and `blobs/` into the output folder, every file atomically.
//!
//! [`showcase`] is `neusample scene`: several materials in one scene, the baseline
//! against the best sampler per material at equal time.
//!
//! Files: `config` (names, [`DemoConfig`], run sizes, the materials evaluated), `pipeline`
//! ([`run`]), `fixtures` ([`regenerate_fixtures`]), `report` (the JSON schema), `markdown`
//! ([`markdown()`]), [`figures`] and [`table`] (every built-in material under two lightings,
//! `neusample table`).

mod config;
pub mod figures;
mod fixtures;
mod markdown;
mod pipeline;
mod report;
pub mod showcase;
pub mod table;

pub use config::{
    neural_fixture, resolve_demo_material, resolve_source, DemoConfig, DemoMaterial, Sky, BASELINE,
    COSINE, DEFAULT_MATERIALS, NEURAL_SUFFIX, ORACLE,
};
pub use fixtures::{fixtures_dir, regenerate_fixtures, FixtureSet};
pub use markdown::{markdown, SMOKE_LINE};
pub use pipeline::run;
pub use report::{
    FigureReport, MaterialReport, MethodReport, NeuralReport, ReferenceReport, RenderReport,
    RenderSetup, Report, REPORT_SCHEMA,
};
pub use table::{Lighting, TableConfig};
