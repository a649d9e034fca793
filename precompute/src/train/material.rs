//! Ground truth of a material: conditions and tabulated targets from `crate::groundtruth`.

use crate::groundtruth;
use crate::materials::Material;

use super::data::{GtCondition, TargetSource};

/// Draws training conditions of a material with [`groundtruth::batch`].
pub struct MaterialSource<'a> {
    material: &'a dyn Material,
}

impl<'a> MaterialSource<'a> {
    /// The source of `material`.
    #[must_use]
    pub fn new(material: &'a dyn Material) -> Self {
        MaterialSource { material }
    }
}

impl TargetSource for MaterialSource<'_> {
    fn draw(&self, n: usize, res: usize, seed: u64) -> anyhow::Result<Vec<GtCondition>> {
        Ok(groundtruth::batch(self.material, n, res, seed)
            .into_iter()
            .map(|(c, target)| GtCondition {
                phi: c.phi,
                wi: c.wi,
                target,
            })
            .collect())
    }
}
