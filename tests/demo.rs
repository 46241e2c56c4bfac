//! The demos' claims on smaller configurations and fresh seeds. Rock drill: the
//! claims marked met (the deflection model lowers the error, the hybrid beats the network alone
//! with the small training set, this project's best pipeline with the small set is near the
//! measurement noise and beats the paper's pipelines with the large one) each hold on at least
//! two of three seeds, and the nominal deflection model removes a minor share of the error. Industrial:
//! the orderings of the ANN paper that hold on its twin. A sweep over seeds summarises the runs
//! of its seeds.

use armcomp_learn::SparrowParams;
use armcomp_repro::demos::industrial;
use armcomp_repro::demos::rock_drill::{Config, claims, collection_order, paper_grid, run, sweep};

use crate::common::Scratch;
use rand::SeedableRng;
use rand::rngs::StdRng;

/// The reproduction page's claims hold on about two seeds in three, not on every seed: each claim is
/// checked to hold on at least two of three fresh seeds, and the deflection model's minor
/// share on the mean over them.
#[test]
fn rock_drill_demo_orders_the_pipelines_as_claimed() {
    use rayon::prelude::*;
    // Grouped as the paper collected them: the small set holds two settings of the telescopes.
    // A hundred targets, so the deflection model's share of the error is measured to a few
    // per cent.
    let config = Config {
        large: 600,
        small: 300,
        targets: 100,
        search: SparrowParams {
            population: 15,
            iterations: 30,
            ..SparrowParams::default()
        },
        max_epochs: 300,
        ..Config::paper(20_261_121)
    };
    let seeds = [20_261_121, 20_261_131, 20_261_141];
    let tables: Vec<_> = seeds
        .par_iter()
        .map(|&seed| run(&Config { seed, ..config.clone() }).unwrap())
        .collect();
    let per_seed: Vec<Vec<(String, bool)>> = tables.iter().map(|t| claims(t, &config)).collect();
    // The orderings the reproduction page marks as met; "every learned row beats the deflection model
    // and more poses beat fewer" and "the hybrid helps most with few poses" it reports as
    // holding on five or six seeds of eight only, and are not checked.
    let checked = [
        "the nominal deflection model lowers the error",
        "the hybrid beats SSA-BP alone",
        "best pipeline with 300 poses within twice",
        "best pipeline with 300 poses beats",
    ];
    let mut matched = 0;
    for (k, (claim, _)) in per_seed[0].iter().enumerate() {
        if !checked.iter().any(|c| claim.starts_with(c)) {
            continue;
        }
        matched += 1;
        let held = per_seed.iter().filter(|c| c[k].1).count();
        assert!(held >= 2, "`{claim}` held on {held} of 3 seeds: {tables:#?}");
    }
    assert_eq!(matched, checked.len(), "claims renamed: {:?}", per_seed[0]);
    // The nominal deflection model removes a minor share: servo scales and zeros, geometry and
    // joint compliance dominate the error and change sign over the workspace (the paper's
    // Table I: 13 % of the mean, 4 % of the variance).
    let total = |name: &str, of: fn(&armcomp_repro::demos::Row) -> f64| -> f64 {
        tables.iter().map(|t| of(t.row(name).unwrap())).sum()
    };
    assert!(
        total("deflection only", |r| r.mean_abs_z_mm) > 0.75 * total("original", |r| r.mean_abs_z_mm),
        "{tables:#?}"
    );
    assert!(
        total("deflection only", |r| r.variance_mm2) > 0.7 * total("original", |r| r.variance_mm2),
        "{tables:#?}"
    );
}

#[test]
fn seed_sweep_summarises_the_runs_of_its_seeds() {
    let config = Config {
        large: 240,
        small: 80,
        targets: 8,
        search: SparrowParams {
            population: 8,
            iterations: 5,
            ..SparrowParams::default()
        },
        max_epochs: 60,
        grouped: true,
        ..Config::paper(20_261_122)
    };
    let done = std::sync::Mutex::new(Vec::new());
    let summary = sweep(&config, 3, &|s| done.lock().unwrap().push(s)).unwrap();
    let mut done = done.into_inner().unwrap();
    done.sort_unstable();
    assert_eq!(done, [20_261_122, 20_261_123, 20_261_124]);
    assert_eq!(summary.seeds, done);
    // Each seed run on its own gives the same errors.
    let alone: Vec<_> = done
        .iter()
        .map(|&seed| run(&Config { seed, ..config.clone() }).unwrap())
        .collect();
    for (i, row) in summary.rows.iter().enumerate() {
        let mut v: Vec<f64> = alone.iter().map(|t| t.rows[i].mean_abs_z_mm).collect();
        assert_eq!(row.name, alone[0].rows[i].name);
        v.sort_by(f64::total_cmp);
        let mean = (v[0] + v[1] + v[2]) / 3.0;
        assert!((row.mean_mm - mean).abs() <= 1e-12 * mean, "{row:?} vs {v:?}");
        assert_eq!((row.min_mm, row.median_mm, row.max_mm), (v[0], v[1], v[2]), "{row:?}");
    }
    let wins = alone
        .iter()
        .filter(|t| {
            let z = |name: &str| t.row(name).unwrap().mean_abs_z_mm;
            z("deflection + SSA-BP, 80 poses") < z("SSA-BP only, 80 poses")
        })
        .count();
    let claim = summary
        .claims
        .iter()
        .find(|c| c.claim == "the hybrid beats SSA-BP alone with 80 poses")
        .unwrap();
    assert_eq!((claim.held, claim.of), (wins, 3));
    assert!(sweep(&config, 0, &|_| {}).is_err());
}

#[test]
fn grouped_collection_measures_one_telescope_setting_after_another() {
    let grid = paper_grid();
    let order = collection_order(grid.clone(), &mut StdRng::seed_from_u64(3));
    // Every grid pose once.
    let key = |q: &Vec<f64>| q.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    let mut a: Vec<_> = grid.iter().map(key).collect();
    let mut b: Vec<_> = order.iter().map(key).collect();
    a.sort();
    b.sort();
    assert_eq!(a, b);
    // Six settings of (j3, j7), each a run of 3^5 = 243 consecutive poses.
    let settings: Vec<(f64, f64)> = order.chunks(243).map(|c| (c[0][2], c[0][6])).collect();
    assert_eq!(settings.len(), 6);
    for (run, &(j3, j7)) in order.chunks(243).zip(&settings) {
        assert!(run.iter().all(|q| q[2] == j3 && q[6] == j7));
    }
    let mut distinct = settings.clone();
    distinct.sort_by(|x, y| x.partial_cmp(y).unwrap());
    distinct.dedup();
    assert_eq!(distinct.len(), 6);
    // Shuffled, and the same for the same seed.
    assert_ne!(order, grid);
    assert_eq!(order, collection_order(grid, &mut StdRng::seed_from_u64(3)));
}

#[test]
fn industrial_demo_orders_the_pipelines_as_claimed() {
    let config = industrial::Config {
        pool: 600,
        identification: 60,
        training: 150,
        targets: 20,
        ..industrial::Config::paper(20_260_512)
    };
    let table = industrial::run(&config).unwrap();
    let mean = |name: &str| table.row(name).unwrap_or_else(|| panic!("row {name}")).mean_mm;
    let before = mean("before (nominal)");
    let poe = mean("POE identification");
    // Geometric identification removes most of the error, POE more than DH.
    assert!(poe < before / 5.0, "{table:#?}");
    assert!(poe < mean("DH identification"), "{table:#?}");
    // The ANN removes part of what POE leaves, whichever training points it gets ...
    for row in &table.rows[3..] {
        assert!(row.mean_mm < poe, "{}: {table:#?}", row.name);
    }
    // ... most with points near the task's path.
    assert!(
        mean("POE + ANN, trajectory-similar points, QRS pool") < mean("POE + ANN, arbitrary points, QRS pool"),
        "{table:#?}"
    );
    // Every test target is in every row, and the report plots the table.
    assert!(table.rows.iter().all(|r| r.errors_mm.len() == config.targets));
    let dir = Scratch::new("industrial-report");
    let page = armcomp_repro::demos::report::write(&dir.0, std::slice::from_ref(&table)).unwrap();
    let html = std::fs::read_to_string(page).unwrap();
    for (kind, shows) in [
        ("bars", "POE identification"),
        ("histogram", "before: before (nominal)"),
        ("axes", "before: before (nominal)"),
    ] {
        let name = format!("1-industrial-twin-{kind}.svg");
        assert!(html.contains(&name));
        let svg = std::fs::read_to_string(dir.0.join(name)).unwrap();
        assert!(svg.contains(shows), "{kind}");
    }
}
