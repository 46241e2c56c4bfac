//! `mlp`: the plain back-propagation network (the ANN paper's compensation network), trained by
//! gradient from a seeded Glorot initialisation.

use armcomp_core::{FitControl, FittedPredictor, PredictorSpec, Result, TrainingSet};
use rand::SeedableRng;
use rand::rngs::StdRng;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::Samples;
use crate::network::Network;
use crate::train::{NetData, TrainingParams, train};

pub(crate) fn default_hidden() -> Vec<usize> {
    vec![20]
}

/// A multilayer perceptron: one or two tanh hidden layers, linear outputs, trained by Adam or
/// Levenberg–Marquardt on standardised inputs and targets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MlpSpec {
    /// Widths of the one or two tanh hidden layers.
    #[serde(default = "default_hidden")]
    pub hidden: Vec<usize>,
    /// Gradient training settings.
    #[serde(default)]
    pub training: TrainingParams,
    /// Seed of the initial weights, the held-out split and the mini-batch order.
    #[serde(default)]
    pub seed: u64,
}

impl Default for MlpSpec {
    fn default() -> Self {
        MlpSpec {
            hidden: default_hidden(),
            training: TrainingParams::default(),
            seed: 0,
        }
    }
}

#[typetag::serde(name = "mlp")]
impl PredictorSpec for MlpSpec {
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
        let samples = Samples::check(data, 2)?;
        let net = Network::new(samples.n_inputs, &self.hidden, samples.n_outputs)?;
        self.training.check(net.n_params())?;
        let mut rng = StdRng::seed_from_u64(self.seed);
        let data = NetData::new(&samples, self.training.validation_fraction, &mut rng);
        let mut params = net.init(&mut rng);
        train(&net, &mut params, &data, &self.training, &mut rng, control)?;
        Ok(Box::new(data.fitted(net, params)?))
    }
}
