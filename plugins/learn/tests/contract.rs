//! What every predictor promises: same seed, same bytes; a serde round trip predicts the same
//! bits; no allocation after the first prediction; bad training data and settings give errors
//! that say what was expected; the robot file's `[predictor]` selects them.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use armcomp_core::{Error, FittedPredictor, Limits, PredictorSpec, RobotFile, TrainingSet};
use armcomp_learn::{
    GpHyperParams, GpSpec, GradientMethod, KnnSpec, KnnWeighting, MlpSpec, RidgeSpec, SparrowParams, SsaBpSpec,
    Standardizer, TrainingParams,
};

use crate::common::Data;
use crate::common::RANGES;

/// Counts this thread's allocations, so tests running in parallel do not disturb each other.
struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|a| a.set(a.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|a| a.set(a.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn small_training() -> TrainingParams {
    TrainingParams {
        max_epochs: 15,
        ..TrainingParams::default()
    }
}

/// Small, fast settings of every predictor (both network trainers, two hidden layers, both GP
/// kernel sharings), with `seed`.
fn specs(seed: u64) -> Vec<(&'static str, Box<dyn PredictorSpec>)> {
    vec![
        (
            "ssa_bp",
            Box::new(SsaBpSpec {
                hidden: vec![8],
                search: SparrowParams {
                    population: 10,
                    iterations: 5,
                    ..SparrowParams::default()
                },
                fitness_on_validation: true,
                refine: small_training(),
                seed,
            }),
        ),
        (
            "mlp adam",
            Box::new(MlpSpec {
                hidden: vec![6, 5],
                training: small_training(),
                seed,
            }),
        ),
        (
            "mlp lm",
            Box::new(MlpSpec {
                hidden: vec![6, 5],
                training: TrainingParams {
                    method: GradientMethod::LevenbergMarquardt,
                    max_epochs: 4,
                    ..TrainingParams::default()
                },
                seed,
            }),
        ),
        (
            "gp shared",
            Box::new(GpSpec {
                restarts: 1,
                max_iterations: 8,
                max_optimization_samples: 40,
                seed,
                ..GpSpec::default()
            }),
        ),
        (
            "gp per output",
            Box::new(GpSpec {
                kernels: armcomp_learn::KernelSharing::PerOutput,
                restarts: 1,
                max_iterations: 8,
                max_optimization_samples: 40,
                seed,
                ..GpSpec::default()
            }),
        ),
        (
            "ridge",
            Box::new(RidgeSpec {
                lambda: 1e-4,
                degree: 2,
                trig: true,
            }),
        ),
        (
            "knn",
            Box::new(KnnSpec {
                k: 4,
                weighting: KnnWeighting::InverseDistance,
            }),
        ),
    ]
}

fn bytes(model: &dyn FittedPredictor) -> String {
    serde_json::to_string(model).unwrap()
}

#[test]
fn same_seed_same_bytes_other_seed_other_model() {
    let data = Data::residuals(60, 11);
    for ((name, a), (_, b)) in specs(1).into_iter().zip(specs(2)) {
        let first = bytes(a.fit(&data.set(7, 3)).unwrap().as_ref());
        let again = bytes(a.fit(&data.set(7, 3)).unwrap().as_ref());
        assert_eq!(first, again, "{name}: two fits with the same seed differ");
        // Ridge and kNN draw no random numbers.
        if !name.starts_with("ridge") && !name.starts_with("knn") {
            let other = bytes(b.fit(&data.set(7, 3)).unwrap().as_ref());
            assert_ne!(first, other, "{name}: another seed gave the same model");
        }
    }
}

#[test]
fn serde_round_trip_predicts_same_bits() {
    let data = Data::residuals(60, 12);
    let probe = Data::residuals(10, 13);
    for (name, spec) in specs(3) {
        let model = spec.fit(&data.set(7, 3)).unwrap();
        let text = bytes(model.as_ref());
        let back: Box<dyn FittedPredictor> = serde_json::from_str(&text).unwrap();
        assert_eq!(bytes(back.as_ref()), text, "{name}: JSON changed in a round trip");
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        let mut scratch = Vec::new();
        for q in probe.inputs.chunks(7) {
            model.predict_into(q, &mut a, &mut scratch);
            back.predict_into(q, &mut b, &mut scratch);
            assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name}: prediction at {q:?}");
            let has_std = model.predict_std_into(q, &mut a, &mut scratch);
            assert_eq!(has_std, back.predict_std_into(q, &mut b, &mut scratch));
            assert_eq!(has_std, name.starts_with("gp"));
            if has_std {
                assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "{name}: std at {q:?}");
            }
        }
    }
}

#[test]
fn prediction_allocates_only_on_first_call() {
    let data = Data::residuals(60, 14);
    let probe = Data::residuals(5, 15);
    for (name, spec) in specs(4) {
        let model = spec.fit(&data.set(7, 3)).unwrap();
        let mut out = [0.0; 3];
        let mut scratch = Vec::new();
        model.predict_into(&probe.inputs[..7], &mut out, &mut scratch);
        model.predict_std_into(&probe.inputs[..7], &mut out, &mut scratch);
        let before = ALLOCATIONS.with(Cell::get);
        for q in probe.inputs.chunks(7) {
            model.predict_into(q, &mut out, &mut scratch);
            model.predict_std_into(q, &mut out, &mut scratch);
        }
        assert_eq!(ALLOCATIONS.with(Cell::get), before, "{name}: prediction allocated");
    }
}

#[test]
fn jacobians_match_central_differences_of_the_prediction() {
    let data = Data::residuals(60, 17);
    let probe = Data::residuals(6, 18);
    for (name, spec) in specs(6) {
        let model = spec.fit(&data.set(7, 3)).unwrap();
        let (mut value, mut jac, mut scratch) = ([0.0; 3], [0.0; 21], Vec::new());
        let has = model.predict_jacobian_into(&probe.inputs[..7], &mut value, &mut jac, &mut scratch);
        // The networks and the GP are smooth; ridge and kNN do not offer a derivative.
        assert_eq!(has, !name.starts_with("ridge") && !name.starts_with("knn"), "{name}");
        if !has {
            continue;
        }
        let before = ALLOCATIONS.with(Cell::get);
        for q in probe.inputs.chunks(7) {
            assert!(model.predict_jacobian_into(q, &mut value, &mut jac, &mut scratch));
            let mut plain = [0.0; 3];
            model.predict_into(q, &mut plain, &mut scratch);
            for o in 0..3 {
                assert!(
                    (value[o] - plain[o]).abs() <= 1e-12 * (1.0 + plain[o].abs()),
                    "{name}: value"
                );
            }
            for j in 0..7 {
                let h = 1e-6 * (1.0 + q[j].abs());
                let (mut up, mut down) = (q.to_vec(), q.to_vec());
                up[j] += h;
                down[j] -= h;
                let (mut fu, mut fd) = ([0.0; 3], [0.0; 3]);
                model.predict_into(&up, &mut fu, &mut scratch);
                model.predict_into(&down, &mut fd, &mut scratch);
                for o in 0..3 {
                    let numeric = (fu[o] - fd[o]) / (2.0 * h);
                    let analytic = jac[o * 7 + j];
                    assert!(
                        (analytic - numeric).abs() <= 1e-5 * (1.0 + numeric.abs()),
                        "{name}: ∂out{o}/∂in{j} = {analytic}, central difference {numeric}"
                    );
                }
            }
        }
        // The allocations above are the probe vectors of the differences only (2 per input).
        assert_eq!(
            ALLOCATIONS.with(Cell::get) - before,
            6 * 7 * 2,
            "{name}: the Jacobian allocated"
        );
    }
}

#[test]
fn bad_training_sets_are_errors() {
    let data = Data::residuals(30, 16);
    let ranges = joint_ranges();
    let mut nan_inputs = data.inputs.clone();
    nan_inputs[7 * 4 + 2] = f64::NAN;
    for (name, spec) in specs(5) {
        let short = TrainingSet {
            targets: &data.targets[..data.targets.len() - 1],
            ..data.set(7, 3)
        };
        match spec.fit(&short) {
            Err(Error::Dimension { expected, got, .. }) => assert_eq!((expected, got), (90, 89), "{name}"),
            other => panic!("{name}: short targets gave {other:?}"),
        }
        let ragged = TrainingSet {
            inputs: &data.inputs[..data.inputs.len() - 3],
            ..data.set(7, 3)
        };
        assert!(
            matches!(spec.fit(&ragged), Err(Error::InvalidArgument { what, reason }) if what == "training set" && reason.contains("whole number of rows")),
            "{name}"
        );
        let nan = TrainingSet {
            inputs: &nan_inputs,
            ..data.set(7, 3)
        };
        match spec.fit(&nan) {
            Err(e @ Error::InvalidArgument { .. }) => {
                assert!(
                    e.to_string().contains("training set: input 2 of row 4 is NaN"),
                    "{name}: {e}"
                )
            }
            other => panic!("{name}: NaN input gave {other:?}"),
        }
        let none = TrainingSet {
            n_inputs: 0,
            ..data.set(7, 3)
        };
        assert!(matches!(spec.fit(&none), Err(Error::InvalidArgument { .. })), "{name}");
        let few_ranges = TrainingSet {
            input_ranges: &ranges[..6],
            ..data.set(7, 3)
        };
        match spec.fit(&few_ranges) {
            Err(Error::Dimension { expected, got, .. }) => assert_eq!((expected, got), (7, 6), "{name}"),
            other => panic!("{name}: six ranges for seven inputs gave {other:?}"),
        }
        let mut inverted = ranges.clone();
        inverted[3] = Some(Limits { lower: 1.0, upper: 0.0 });
        match spec.fit(&TrainingSet {
            input_ranges: &inverted,
            ..data.set(7, 3)
        }) {
            Err(e @ Error::InvalidArgument { .. }) => {
                assert!(
                    e.to_string().contains("training set: range of input 3 is [1, 0]"),
                    "{name}: {e}"
                )
            }
            other => panic!("{name}: an inverted range gave {other:?}"),
        }
    }
}

/// The rock-drill's joint ranges as the robot would declare them.
fn joint_ranges() -> Vec<Option<Limits>> {
    RANGES
        .iter()
        .map(|&(lower, upper)| Some(Limits { lower, upper }))
        .collect()
}

#[test]
fn a_joint_that_held_still_is_ignored_by_every_predictor() {
    // j7 jitters by 10 µm around 30 mm in the training data: below the input scale floor.
    let mut data = Data::residuals(60, 21);
    for (i, row) in data.inputs.chunks_exact_mut(7).enumerate() {
        row[6] = 0.03 + 1e-5 * (i % 2) as f64;
    }
    let ranges = joint_ranges();
    let set = TrainingSet {
        input_ranges: &ranges,
        ..data.set(7, 3)
    };
    let probe = Data::residuals(3, 22);
    for (name, spec) in specs(8) {
        let model = spec.fit(&set).unwrap();
        let mut scratch = Vec::new();
        for q in probe.inputs.chunks(7) {
            // Anywhere in its range, even far from where it held still, j7 changes nothing.
            let (mut at_zero, mut at_end) = ([0.0; 3], [0.0; 3]);
            let (mut lo, mut hi) = (q.to_vec(), q.to_vec());
            lo[6] = 0.0;
            hi[6] = 0.063;
            model.predict_into(&lo, &mut at_zero, &mut scratch);
            model.predict_into(&hi, &mut at_end, &mut scratch);
            assert_eq!(at_zero, at_end, "{name}: the held-still joint moved the prediction");
            let (mut value, mut jac) = ([0.0; 3], [0.0; 21]);
            if model.predict_jacobian_into(&lo, &mut value, &mut jac, &mut scratch) {
                assert!((0..3).all(|o| jac[o * 7 + 6] == 0.0), "{name}: ∂/∂j7 = {jac:?}");
            }
        }
    }
}

#[test]
fn inputs_are_scaled_by_at_least_their_range() {
    // Column 0 at two extensions 5 mm apart, column 1 spread across its range, column 2
    // without a declared range.
    let rows: Vec<[f64; 3]> = (0..8)
        .map(|i| [if i < 6 { 0.1 } else { 0.105 }, 0.01 * i as f64, 0.003 * i as f64])
        .collect();
    let values: Vec<f64> = rows.iter().flatten().copied().collect();
    let ranges = [
        Some(Limits {
            lower: 0.0,
            upper: 0.105,
        }),
        Some(Limits {
            lower: 0.0,
            upper: 0.07,
        }),
        None,
    ];
    let s = Standardizer::fit_inputs(&values, 3, &ranges);
    let std_of = |j: usize| {
        let m = rows.iter().map(|r| r[j]).sum::<f64>() / 8.0;
        (rows.iter().map(|r| (r[j] - m).powi(2)).sum::<f64>() / 8.0).sqrt()
    };
    // sd of {100 mm ×6, 105 mm ×2} = 5 mm · √(0.75 · 0.25) = 2.2 mm < the uniform sd 30.3 mm.
    assert!(
        std_of(0) > 2e-3 && (s.scale[0] - 0.105 / 12f64.sqrt()).abs() < 1e-15,
        "{:?}",
        s.scale
    );
    // 0, 10, ..., 70 mm: sd 22.9 mm > the uniform sd of 0..70 mm, 20.2 mm.
    assert!((s.scale[1] - std_of(1)).abs() < 1e-15 && std_of(1) > 0.07 / 12f64.sqrt());
    assert!((s.scale[2] - std_of(2)).abs() < 1e-15);
    let mut z = [0.0; 3];
    s.apply(&[0.0, 0.0, 0.0], &mut z);
    // The far end of the telescope is 3.3 of its scales away, not 47 of its 2.2 mm.
    assert!((z[0] + 0.10125 / (0.105 / 12f64.sqrt())).abs() < 1e-12, "{z:?}");
}

#[test]
fn bad_settings_are_errors() {
    let data = Data::residuals(30, 17);
    let set = data.set(7, 3);
    let message = |spec: &dyn PredictorSpec| match spec.fit(&set) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("{spec:?} fitted"),
    };
    assert!(
        message(&MlpSpec {
            hidden: vec![],
            ..MlpSpec::default()
        })
        .contains("hidden")
    );
    assert!(
        message(&MlpSpec {
            hidden: vec![4, 4, 4],
            ..MlpSpec::default()
        })
        .contains("one or two")
    );
    let lm = TrainingParams {
        method: GradientMethod::LevenbergMarquardt,
        ..TrainingParams::default()
    };
    assert!(
        message(&MlpSpec {
            hidden: vec![200, 50],
            training: lm,
            seed: 0
        })
        .contains("at most 2000 weights")
    );
    let ssa = |search: SparrowParams| SsaBpSpec {
        search,
        ..SsaBpSpec::default()
    };
    assert!(
        message(&ssa(SparrowParams {
            safety_threshold: 0.3,
            ..SparrowParams::default()
        }))
        .contains("[0.5, 1]")
    );
    assert!(
        message(&ssa(SparrowParams {
            producer_share: 1.0,
            ..SparrowParams::default()
        }))
        .contains("no scroungers")
    );
    let fixed = GpHyperParams {
        length_scales: vec![1.0; 3],
        signal_std: 1.0,
        noise_std: 0.1,
    };
    assert!(
        message(&GpSpec {
            fixed: Some(fixed),
            ..GpSpec::default()
        })
        .contains("expected 7 values, got 3")
    );
    assert!(
        message(&RidgeSpec {
            degree: 3,
            ..RidgeSpec::default()
        })
        .contains("1 or 2")
    );
    assert!(
        message(&KnnSpec {
            k: 31,
            ..KnnSpec::default()
        })
        .contains("at least 31 samples")
    );
}

#[test]
fn corrupt_model_files_are_errors() {
    let data = Data::residuals(30, 18);
    for (name, spec) in specs(6) {
        let mut json = serde_json::to_value(spec.fit(&data.set(7, 3)).unwrap().as_ref()).unwrap();
        // Drop one value of the first long array: parameters, weights, alpha or inputs.
        let field = ["params", "weights", "train_inputs"]
            .into_iter()
            .find(|f| json.get(*f).is_some())
            .unwrap();
        json[field].as_array_mut().unwrap().pop();
        let back: Result<Box<dyn FittedPredictor>, _> = serde_json::from_value(json);
        assert!(back.is_err(), "{name}: a truncated {field} was accepted");
    }
}

/// A robot file's `[predictor]` table picks the predictor by `type` and fits.
#[test]
fn robot_file_selects_predictor() {
    let _ = armcomp_chains::plugins();
    let base = include_str!("../../../robots/rock-drill.toml");
    let data = Data::residuals(40, 19);
    for table in [
        "type = \"gp\"\nkernels = \"per_output\"\nrestarts = 0\nmax_iterations = 5",
        "type = \"ssa_bp\"\nhidden = [6]\nseed = 3\n[predictor.search]\npopulation = 8\niterations = 3\n[predictor.refine]\nmax_epochs = 5",
        "type = \"mlp\"\n[predictor.training]\nmethod = \"levenberg_marquardt\"\nmax_epochs = 3",
        "type = \"ridge\"\ntrig = true",
        "type = \"knn\"\nk = 3\nweighting = \"inverse_distance\"",
    ] {
        let text = format!("{base}\n[predictor]\n{table}\n");
        let file: RobotFile = toml::from_str(&text).unwrap_or_else(|e| panic!("{table}: {e}"));
        let spec = file.predictor.expect("the predictor table is read");
        let model = spec.fit(&data.set(7, 3)).unwrap();
        assert_eq!((model.n_inputs(), model.n_outputs()), (7, 3));
    }
    let text = format!("{base}\n[predictor]\ntype = \"gp\"\nrestart = 2\n");
    let err = toml::from_str::<RobotFile>(&text).unwrap_err().to_string();
    assert!(err.contains("restart"), "{err}");
}
