//! Time of the whole calibration (UIC: trajectory fit with Qc by marginal likelihood, clock offset,
//! closed form, refinement, covariance) for 1k, 10k and 100k DVL samples.
//!
//! `cargo bench --bench calibration` (optionally `-- 1000 10000` for other sizes). Data: the
//! lively sinusoid motion (the sampled motions stop at 4000 s) with the default truth (70 ms
//! offset, 1 % scale), camera and DVL at 10 Hz, N / 10 seconds long. Small sizes are repeated and the median is reported. Prints a markdown
//! table.

use std::time::Instant;

use dvlcal::calib::align::{AlignOptions, align_clocks};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::{MotionKind, SimConfig, simulate};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let sizes: Vec<usize> = {
        let args: Vec<usize> = std::env::args()
            .skip(1)
            .filter_map(|a| a.parse().ok())
            .collect();
        if args.is_empty() {
            vec![1_000, 10_000, 100_000]
        } else {
            args
        }
    };
    println!(
        "| DVL samples | poses | runs | calibration (median) | us/sample | ratio to previous size | \
         rotation error (deg) | lever arm error (mm) | offset error (ms) | of which clock alignment |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut prev: Option<f64> = None;
    for n in sizes {
        let cfg = SimConfig {
            duration_s: n as f64 / 10.0,
            seed: 7,
            motion: MotionKind::Sinusoid,
            ..SimConfig::default()
        };
        let ds = simulate(&cfg).expect("simulate");
        let reps = if n <= 1_000 {
            5
        } else if n <= 10_000 {
            3
        } else {
            1
        };
        let opts = CalibOptions::default();
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..reps {
            let t0 = Instant::now();
            let out = calibrate(&ds.poses, &ds.dvl, &opts).expect("calibrate");
            times.push(t0.elapsed().as_secs_f64());
            last = Some(out);
        }
        let out = last.expect("one run");
        let t = median(times);
        // The global clock alignment on its own (it runs inside every calibration), median of 5.
        let align: Vec<f64> = (0..5)
            .map(|_| {
                let t0 = Instant::now();
                align_clocks(
                    &out.fitted,
                    &out.observations,
                    None,
                    &AlignOptions::default(),
                )
                .expect("alignment");
                t0.elapsed().as_secs_f64()
            })
            .collect();
        let align = median(align);
        let truth = ds.truth;
        let rot = dvlcal::lie::so3::log(&(out.params.r_dvl_cam() * truth.r_dvl_cam().transpose()))
            .norm()
            .to_degrees();
        println!(
            "| {} | {} | {reps} | {t:.3} s | {:.1} | {} | {rot:.4} | {:.2} | {:.3} | {:.3} s ({:.1} %) |",
            ds.dvl.len(),
            ds.poses.len(),
            1e6 * t / ds.dvl.len() as f64,
            prev.map_or("-".to_string(), |p| format!("{:.1}", t / p)),
            1e3 * (out.params.lever_arm_cam_m() - truth.lever_arm_cam_m()).norm(),
            1e3 * (out.params.time_offset_s - truth.time_offset_s).abs(),
            align,
            100.0 * align / t
        );
        prev = Some(t);
    }
}
