//! The paper's two simulations (Sec. V) as a Monte Carlo benchmark, with the Cramer-Rao bound.
//!
//! `cargo bench --bench paper_sims` prints markdown tables (docs/accuracy.md, "Calibration").
//! `DVLCAL_BENCH_QUICK=1` runs a few seeds at small sizes only (a smoke run);
//! `DVLCAL_BENCH_THREADS` sets the worker threads (default: all CPUs).
//!
//! - Sim 1 (bias elimination): clock offset 0, true twists of the calm-then-rotate motion plus
//!   independent Gaussian perturbations of known covariance (standing in for the GP's posterior
//!   uncertainty), DVL noise 0.01 m/s; the closed form without and with bias elimination.
//! - Sim 2 (excitation): clock offset 0.07 s, strong (calm-then-rotate) and weak rotation; the
//!   whole calibration from UIC and block-coordinate descent (BCD) from a random guess around the
//!   truth (5 deg, 5 cm, scale 1, offset 0).
//! - CRB: the Cramer-Rao bound of the eight parameters at the true trajectory and calibration,
//!   against the RMSE of the strong-rotation runs.
//!
//! Every RMSE comes with a 95% bootstrap confidence interval over the seeds (2000 resamples,
//! percentile interval).

mod common;

use std::time::Instant;

use common::{par_map, threads};

use dvlcal::calib::closed_form::{ClosedFormRow, closed_form};
use dvlcal::calib::{CalibOptions, Method, calibrate};
use dvlcal::lie::so3;
use dvlcal::rng::Rng;
use dvlcal::sim::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::trajectory::Knot;
use dvlcal::types::CalibrationParams;
use nalgebra::{Matrix6, Vector3};

const DVL_SIGMA: f64 = 0.01;

fn quick() -> bool {
    std::env::var("DVLCAL_BENCH_QUICK").is_ok_and(|v| !v.is_empty() && v != "0")
}

/// RMSE of values whose squares are `sq`, with a 95% percentile-bootstrap interval.
struct Rmse {
    value: f64,
    lo: f64,
    hi: f64,
}

fn rmse(sq: &[f64]) -> Rmse {
    let n = sq.len();
    if n == 0 {
        return Rmse {
            value: f64::NAN,
            lo: f64::NAN,
            hi: f64::NAN,
        };
    }
    let value = (sq.iter().sum::<f64>() / n as f64).sqrt();
    let mut rng = Rng::new(0xB007);
    let mut boot: Vec<f64> = (0..2000)
        .map(|_| {
            let s: f64 = (0..n)
                .map(|_| sq[(rng.next_u64() % n as u64) as usize])
                .sum();
            (s / n as f64).sqrt()
        })
        .collect();
    boot.sort_by(f64::total_cmp);
    Rmse {
        value,
        lo: boot[49],
        hi: boot[1949],
    }
}

fn fmt(r: &Rmse, scale: f64) -> String {
    let d = |x: f64| {
        let x = x * scale;
        if x == 0.0 || !x.is_finite() {
            format!("{x}")
        } else if x.abs() >= 100.0 {
            format!("{x:.0}")
        } else {
            let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
            format!("{x:.digits$}")
        }
    };
    format!("{} [{}, {}]", d(r.value), d(r.lo), d(r.hi))
}

/// Left-perturbation rotation error `log(R_est R_true^T)` (radians).
fn rot_err(est: &CalibrationParams, truth: &CalibrationParams) -> Vector3<f64> {
    so3::log(&(est.r_dvl_cam() * truth.r_dvl_cam().transpose()))
}

fn sim(n: usize, seed: u64, motion: MotionKind, offset: f64) -> SimDataset {
    let mut truth = SimConfig::default_truth();
    truth.time_offset_s = offset;
    let cfg = SimConfig {
        duration_s: n as f64 / 10.0,
        seed,
        motion,
        dvl_sigma: DVL_SIGMA,
        truth,
        ..SimConfig::default()
    };
    simulate(&cfg).expect("simulate")
}

// ---------------------------------------------------------------------------------------------
// Sim 1: bias elimination.

struct Sim1Run {
    biased: [f64; 3],
    unbiased: [f64; 3],
}

fn sim1_run(n: usize, seed: u64, sd: f64) -> Sim1Run {
    let ds = sim(n, seed, MotionKind::CalmThenRotate, 0.0);
    let truth = ds.truth;
    let cov = Matrix6::identity() * (sd * sd);
    let mut rng = Rng::stream(seed, 1001);
    let rows: Vec<ClosedFormRow> = ds
        .dvl
        .iter()
        .zip(&ds.dvl_truth)
        .take(n)
        .map(|(d, s)| ClosedFormRow {
            v_dvl: d.v,
            twist: s.twist + rng.normal_vec6() * sd,
            twist_cov: cov,
        })
        .collect();
    let err = |bias_corrected: bool| {
        let p = closed_form(&rows, bias_corrected)
            .expect("closed form")
            .params;
        [
            rot_err(&p, &truth).norm().to_degrees().powi(2),
            (p.lever_arm_cam_m() - truth.lever_arm_cam_m()).norm_squared(),
            (p.velocity_scale - truth.velocity_scale).powi(2),
        ]
    };
    Sim1Run {
        biased: err(false),
        unbiased: err(true),
    }
}

fn sim1(quick: bool) {
    let sizes: Vec<(usize, usize)> = if quick {
        vec![(10, 20), (100, 20), (1000, 10)]
    } else {
        vec![
            (10, 200),
            (30, 200),
            (100, 200),
            (300, 200),
            (1000, 200),
            (3000, 100),
            (10000, 50),
        ]
    };
    for sd in [0.02, 0.05] {
        println!(
            "\n### Sim 1: biased vs bias-eliminated closed form, twist perturbation {sd} m/s and \
             {sd} rad/s per axis\n"
        );
        println!(
            "| N | seeds | rotation (deg), biased | bias-eliminated | lever arm (m), biased | \
             bias-eliminated | scale, biased | bias-eliminated |"
        );
        println!("|---|---|---|---|---|---|---|---|");
        for &(n, seeds) in &sizes {
            let runs = par_map(seeds, |s| sim1_run(n, s, sd));
            let col = |f: &dyn Fn(&Sim1Run) -> f64| rmse(&runs.iter().map(f).collect::<Vec<_>>());
            println!(
                "| {n} | {seeds} | {} | {} | {} | {} | {} | {} |",
                fmt(&col(&|r| r.biased[0]), 1.0),
                fmt(&col(&|r| r.unbiased[0]), 1.0),
                fmt(&col(&|r| r.biased[1]), 1.0),
                fmt(&col(&|r| r.unbiased[1]), 1.0),
                fmt(&col(&|r| r.biased[2]), 1.0),
                fmt(&col(&|r| r.unbiased[2]), 1.0),
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Sim 2: excitation, UIC vs BCD, and the CRB.

/// Squared errors of one calibration: per-component rotation (rad^2, left perturbation), lever
/// arm (m^2), scale, offset (s^2); whether the lever arm was judged weak.
#[derive(Clone)]
struct CalRun {
    e: [f64; 8],
    lever_weak: bool,
}

impl CalRun {
    fn rot_deg2(&self) -> f64 {
        (self.e[0] + self.e[1] + self.e[2]) * 1f64.to_degrees().powi(2)
    }
    fn lever2(&self) -> f64 {
        self.e[3] + self.e[4] + self.e[5]
    }
}

struct Sim2Run {
    uic: Option<CalRun>,
    bcd: Option<CalRun>,
    /// Diagonal of the CRB (strong rotation, when asked for).
    crb: Option<[f64; 8]>,
}

fn cal_run(ds: &SimDataset, truth: &CalibrationParams, method: Method) -> Option<CalRun> {
    let opts = CalibOptions {
        method,
        ..CalibOptions::default()
    };
    let out = calibrate(&ds.poses, &ds.dvl, &opts).ok()?;
    let p = &out.params;
    let r = rot_err(p, truth);
    let l = p.lever_arm_cam_m() - truth.lever_arm_cam_m();
    let e = [
        r.x * r.x,
        r.y * r.y,
        r.z * r.z,
        l.x * l.x,
        l.y * l.y,
        l.z * l.z,
        (p.velocity_scale - truth.velocity_scale).powi(2),
        (p.time_offset_s - truth.time_offset_s).powi(2),
    ];
    Some(CalRun {
        e,
        lever_weak: !out.verdicts.lever_arm.ok,
    })
}

fn crb_diag(ds: &SimDataset, truth: &CalibrationParams) -> Option<[f64; 8]> {
    let opts = CalibOptions::default();
    let knots: Vec<Knot> = ds
        .truth_poses
        .iter()
        .map(|s| Knot {
            pose: s.pose,
            twist: s.twist,
            rate: s.twist_rate,
        })
        .collect();
    let c = dvlcal::calib::cramer_rao(&ds.poses, &ds.dvl, &knots, truth, &opts).ok()?;
    Some(std::array::from_fn(|k| c[(k, k)]))
}

fn sim2_run(n: usize, seed: u64, motion: MotionKind, with_crb: bool) -> Sim2Run {
    let ds = sim(n, seed, motion, 0.07);
    let truth = ds.truth;
    let mut rng = Rng::stream(seed, 1002);
    let dir = |rng: &mut Rng| {
        let v: Vector3<f64> = rng.normal_vec3();
        v / v.norm()
    };
    let guess = CalibrationParams::from_r_dvl_cam(
        so3::exp(&(dir(&mut rng) * 5f64.to_radians())) * truth.r_dvl_cam(),
        truth.lever_arm_cam_m() + dir(&mut rng) * 0.05,
        1.0,
        0.0,
    );
    Sim2Run {
        uic: cal_run(&ds, &truth, Method::Uic),
        bcd: cal_run(&ds, &truth, Method::Bcd(guess)),
        crb: if with_crb {
            crb_diag(&ds, &truth)
        } else {
            None
        },
    }
}

fn sim2(quick: bool) {
    let sizes: Vec<(usize, usize)> = if quick {
        vec![(10, 4), (100, 4), (500, 4)]
    } else {
        vec![
            (10, 100),
            (30, 100),
            (50, 100),
            (100, 60),
            (500, 24),
            (1000, 16),
            (5000, 4),
        ]
    };
    let crb_sizes = [500, 1000, 5000];
    let mut crb_rows = Vec::new();
    for (motion, name) in [
        (
            MotionKind::CalmThenRotate,
            "strong rotation (calm then rotate)",
        ),
        (MotionKind::WeakRotation, "weak rotation"),
    ] {
        println!("\n### Sim 2: {name}, clock offset 0.07 s\n");
        println!(
            "| N | seeds | method | runs ok | rotation (deg) | lever arm (m) | offset (ms) | \
             scale | lever arm weak |"
        );
        println!("|---|---|---|---|---|---|---|---|---|");
        for &(n, seeds) in &sizes {
            let t0 = Instant::now();
            let with_crb = motion == MotionKind::CalmThenRotate && crb_sizes.contains(&n);
            let runs = par_map(seeds, |s| sim2_run(n, s, motion, with_crb));
            for (mname, pick) in [
                (
                    "UIC",
                    (|r: &Sim2Run| r.uic.clone()) as fn(&Sim2Run) -> Option<CalRun>,
                ),
                ("BCD", |r: &Sim2Run| r.bcd.clone()),
            ] {
                let ok: Vec<CalRun> = runs.iter().filter_map(pick).collect();
                let col = |f: &dyn Fn(&CalRun) -> f64| rmse(&ok.iter().map(f).collect::<Vec<_>>());
                let weak = ok.iter().filter(|r| r.lever_weak).count();
                println!(
                    "| {n} | {seeds} | {mname} | {} | {} | {} | {} | {} | {} |",
                    ok.len(),
                    fmt(&col(&|r| r.rot_deg2()), 1.0),
                    fmt(&col(&|r| r.lever2()), 1.0),
                    fmt(&col(&|r| r.e[7]), 1e3),
                    fmt(&col(&|r| r.e[6]), 1.0),
                    if ok.is_empty() {
                        "-".to_string()
                    } else {
                        format!("{:.0}%", 100.0 * weak as f64 / ok.len() as f64)
                    },
                );
            }
            eprintln!(
                "sim 2 {name} N={n}: {seeds} seeds in {:.1} s",
                t0.elapsed().as_secs_f64()
            );
            if with_crb {
                crb_rows.push((n, runs));
            }
        }
    }
    if crb_rows.is_empty() {
        return;
    }
    println!("\n### Accuracy against the Cramer-Rao bound (strong rotation)\n");
    println!(
        "Per parameter: RMSE over the seeds / sqrt(CRB) averaged over the same seeds (ratio). \
         Rotation components are the left perturbation of R_dvl_cam (deg), lever arm in mm, \
         scale in units of 1e-3, offset in ms.\n"
    );
    let names = [
        "rot x", "rot y", "rot z", "lever x", "lever y", "lever z", "scale", "offset",
    ];
    let units = [
        1f64.to_degrees(),
        1f64.to_degrees(),
        1f64.to_degrees(),
        1e3,
        1e3,
        1e3,
        1e3,
        1e3,
    ];
    print!("| N | method | runs |");
    for nm in names {
        print!(" {nm} |");
    }
    println!();
    println!("|---|---|---|{}", "---|".repeat(8));
    for (n, runs) in &crb_rows {
        let crbs: Vec<[f64; 8]> = runs.iter().filter_map(|r| r.crb).collect();
        if crbs.is_empty() {
            println!("| {n} | CRB unavailable | | | | | | | | | |");
            continue;
        }
        let sd: Vec<f64> = (0..8)
            .map(|k| crbs.iter().map(|c| c[k].max(0.0).sqrt()).sum::<f64>() / crbs.len() as f64)
            .collect();
        print!("| {n} | sqrt(CRB) | {} |", crbs.len());
        for k in 0..8 {
            print!(" {:.3} |", sd[k] * units[k]);
        }
        println!();
        for (mname, pick) in [
            (
                "UIC",
                (|r: &Sim2Run| r.uic.clone()) as fn(&Sim2Run) -> Option<CalRun>,
            ),
            ("BCD", |r: &Sim2Run| r.bcd.clone()),
        ] {
            let ok: Vec<CalRun> = runs.iter().filter_map(pick).collect();
            print!("| {n} | {mname} RMSE (ratio) | {} |", ok.len());
            for k in 0..8 {
                let r = rmse(&ok.iter().map(|c| c.e[k]).collect::<Vec<_>>());
                print!(
                    " {:.3} ({:.2}) [{:.2}, {:.2}] |",
                    r.value * units[k],
                    r.value / sd[k],
                    r.lo / sd[k],
                    r.hi / sd[k]
                );
            }
            println!();
        }
    }
}

fn main() {
    // `cargo bench` passes `--bench`; nothing else is parsed.
    let quick = quick();
    let t0 = Instant::now();
    println!(
        "Threads: {}; {} settings.",
        threads(),
        if quick { "quick" } else { "default" }
    );
    sim1(quick);
    eprintln!("sim 1 done in {:.1} s", t0.elapsed().as_secs_f64());
    sim2(quick);
    eprintln!("total {:.1} s", t0.elapsed().as_secs_f64());
}
