//! Every predictor with its default settings on the paper's larger training-set size (900
//! samples), held-out on 500. Slow in the test profile: run with
//! `cargo test --release -p armcomp-learn --test predictors -- --ignored`.

use armcomp_core::PredictorSpec;
use armcomp_learn::{GpSpec, KnnSpec, MlpSpec, RidgeSpec, SsaBpSpec};

use crate::common::{Data, assert_fits, rms_vs_std};

#[test]
#[ignore]
fn defaults_at_900_samples() {
    let (train, test) = (Data::residuals(900, 31), Data::residuals(500, 32));
    let learners: [(&str, Box<dyn PredictorSpec>, f64); 3] = [
        ("ssa_bp", Box::new(SsaBpSpec::default()), 0.05),
        ("mlp", Box::new(MlpSpec::default()), 0.05),
        ("gp", Box::new(GpSpec::default()), 0.01),
    ];
    for (name, spec, share) in learners {
        assert_fits(name, spec.fit(&train.set(7, 3)).unwrap().as_ref(), &test, share);
    }
    // The baselines: the linear ridge explains part of the residual, the learners most of it.
    let ridge = RidgeSpec::default().fit(&train.set(7, 3)).unwrap();
    let knn = KnnSpec::default().fit(&train.set(7, 3)).unwrap();
    for (c, ((r, std), (k, _))) in rms_vs_std(ridge.as_ref(), &test)
        .into_iter()
        .zip(rms_vs_std(knn.as_ref(), &test))
        .enumerate()
    {
        assert!(r < std && k < std, "output {c}: ridge {r}, knn {k}, std {std}");
        assert!(
            r > 0.05 * std && k > 0.05 * std,
            "output {c}: the baselines should not match the learners"
        );
    }
}
