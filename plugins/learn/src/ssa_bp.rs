//! `ssa_bp`: the deflection paper's sparrow-search-optimised back-propagation network. The
//! sparrow search looks for the weights and biases with the least mean squared error, then
//! gradient training refines the best sparrow.

use armcomp_core::{FitControl, FittedPredictor, PredictorSpec, Result, TrainingSet};
use rand::SeedableRng;
use rand::rngs::StdRng;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, invalid};
use crate::mlp::default_hidden;
use crate::network::Network;
use crate::sparrow::{SparrowParams, sparrow_search};
use crate::train::{NetData, TrainingParams, train};

/// SSA-BP: sparrow search over the flattened weights and biases of a tanh network, then
/// gradient refinement of the best sparrow.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SsaBpSpec {
    /// Widths of the one or two tanh hidden layers.
    #[serde(default = "default_hidden")]
    pub hidden: Vec<usize>,
    /// Sparrow search settings (standardised units: weights searched in `[-bound, bound]`).
    #[serde(default)]
    pub search: SparrowParams,
    /// Score sparrows on the held-out rows instead of the training rows (needs
    /// `refine.validation_fraction > 0`).
    #[serde(default)]
    pub fitness_on_validation: bool,
    /// Gradient refinement of the best sparrow; its `validation_fraction` also sets the held-out
    /// rows of the search.
    #[serde(default)]
    pub refine: TrainingParams,
    /// Seed of the population, the held-out split and the refinement.
    #[serde(default)]
    pub seed: u64,
}

impl Default for SsaBpSpec {
    fn default() -> Self {
        SsaBpSpec {
            hidden: default_hidden(),
            search: SparrowParams::default(),
            fitness_on_validation: false,
            refine: TrainingParams::default(),
            seed: 0,
        }
    }
}

#[typetag::serde(name = "ssa_bp")]
impl PredictorSpec for SsaBpSpec {
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
        let samples = Samples::check(data, 2)?;
        let net = Network::new(samples.n_inputs, &self.hidden, samples.n_outputs)?;
        self.refine.check(net.n_params())?;
        self.search.check()?;
        if self.fitness_on_validation && self.refine.validation_fraction == 0.0 {
            return Err(invalid(
                "fitness_on_validation",
                "needs held-out rows, but refine.validation_fraction is 0".into(),
            ));
        }
        let mut rng = StdRng::seed_from_u64(self.seed);
        let data = NetData::new(&samples, self.refine.validation_fraction, &mut rng);
        let rows = if self.fitness_on_validation {
            &data.held_out
        } else {
            &data.train
        };
        let mut acts = vec![0.0; net.n_activations()];
        let report = sparrow_search(net.n_params(), &self.search, &mut rng, control, |w| {
            data.mse(&net, w, rows, &mut acts)
        })?;
        let mut params = report.best;
        train(&net, &mut params, &data, &self.refine, &mut rng, control)?;
        Ok(Box::new(data.fitted(net, params)?))
    }
}
