//! `dvlcal fit-trajectory`: the continuous-time trajectory and its twists.

use anyhow::{Context, Result, bail};
use nalgebra::Vector6;
use std::path::PathBuf;
use std::time::Instant;

use dvlcal::io::frames_csv::read_tum_with_covariances;
use dvlcal::io::times::read_times;
use dvlcal::io::twist_csv::{TwistRow, write_twist_csv};
use dvlcal::trajectory::{FitOptions, Trajectory};

#[derive(clap::Args)]
pub struct FitArgs {
    /// TUM file of T_world_cam: `timestamp tx ty tz qx qy qz qw` per line, camera clock; the
    /// poses' covariances are read from POSES.frames.csv when it sits beside it.
    #[arg(long)]
    pub poses: PathBuf,
    /// Output CSV of body twists.
    #[arg(long)]
    pub out: PathBuf,
    /// Times to evaluate at, one per line (default: the pose times).
    #[arg(long)]
    pub at: Option<PathBuf>,
    /// Jerk power spectral density, m^2/s^5 (translation) and rad^2/s^5 (rotation): one value
    /// for all six components, or `trans,rot`, or six values; default: chosen by marginal
    /// likelihood.
    #[arg(long, value_delimiter = ',')]
    pub qc: Option<Vec<f64>>,
    /// Pose noise `pos_m,rot_rad`, metres and radians (per axis); default: estimated from the
    /// data.
    #[arg(long, value_delimiter = ',')]
    pub pose_sigma: Option<Vec<f64>>,
}

fn qc_from_arg(v: &[f64]) -> Result<Vector6<f64>> {
    let qc = match v.len() {
        1 => Vector6::repeat(v[0]),
        2 => Vector6::new(v[0], v[0], v[0], v[1], v[1], v[1]),
        6 => Vector6::from_column_slice(v),
        n => bail!("--qc takes 1, 2 or 6 values, got {n}"),
    };
    if qc.iter().any(|q| !(q.is_finite() && *q > 0.0)) {
        bail!("--qc values must be positive and finite");
    }
    Ok(qc)
}

pub fn run(a: FitArgs) -> Result<()> {
    dvlcal::files::refuse_input(
        "--out",
        &a.out,
        std::iter::once(a.poses.as_path()).chain(a.at.as_deref()),
    )?;
    dvlcal::files::prepare_output("--out", &a.out)?;
    let (tum, table) = read_tum_with_covariances(&a.poses, None)?;
    dvlcal::pipeline::unused::pose_sigma_option(&a.poses, table.as_deref(), &crate::given())?;
    let mut opts = FitOptions::default();
    if let Some(q) = &a.qc {
        opts.qc = Some(qc_from_arg(q)?);
    }
    if let Some(s) = &a.pose_sigma {
        if s.len() != 2 || s.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            bail!("--pose-sigma takes two positive values: pos_m,rot_rad");
        }
        opts.pose_sigma = Some((s[0], s[1]));
    }
    let times: Vec<(usize, f64)> = match &a.at {
        Some(p) => read_times(p, tum.epoch)?,
        None => tum
            .lines
            .iter()
            .zip(&tum.poses)
            .map(|(l, p)| (*l, p.t))
            .collect(),
    };
    let start = Instant::now();
    let traj = Trajectory::fit(&tum.poses, &opts)
        .with_context(|| format!("fitting the trajectory to {}", a.poses.display()))?;
    let fit_time = start.elapsed();
    let (t0, t1) = traj.span();
    let at_file = a.at.as_deref().unwrap_or(&a.poses);
    let mut rows = Vec::with_capacity(times.len());
    for (line, t) in &times {
        let s = traj.query(*t).map_err(|_| {
            anyhow::anyhow!(
                "{}:{}: time {} is outside the span of the poses [{}, {}]",
                at_file.display(),
                line,
                tum.epoch.format_abs(*t, 9),
                tum.epoch.format_abs(t0, 9),
                tum.epoch.format_abs(t1, 9)
            )
        })?;
        let sd = s
            .twist_cov
            .map(|c| c.diagonal().map(|x| x.max(0.0).sqrt()))
            .unwrap_or_else(Vector6::zeros);
        rows.push(TwistRow {
            t: *t,
            v: s.twist.fixed_rows::<3>(0).into_owned(),
            w: s.twist.fixed_rows::<3>(3).into_owned(),
            std_v: sd.fixed_rows::<3>(0).into_owned(),
            std_w: sd.fixed_rows::<3>(3).into_owned(),
            dv: s.rate.fixed_rows::<3>(0).into_owned(),
            dw: s.rate.fixed_rows::<3>(3).into_owned(),
        });
    }
    write_twist_csv(&a.out, tum.epoch, &rows)?;
    let r = traj.report();
    println!("poses            {} over {:.3} s", tum.poses.len(), t1 - t0);
    if let Some(t) = &table {
        println!("pose covariances {}", t.display());
    }
    println!(
        "jerk PSD Qc      trans {:.3e}, rot {:.3e} ({})",
        r.qc[0],
        r.qc[3],
        if r.qc_estimated {
            "marginal likelihood"
        } else {
            "given"
        }
    );
    if tum.poses.iter().any(|p| p.cov.is_none()) {
        println!(
            "pose noise       {:.2} mm, {:.3} deg ({})",
            r.pose_sigma.0 * 1e3,
            r.pose_sigma.1.to_degrees(),
            if r.pose_sigma_estimated {
                "estimated"
            } else {
                "given"
            }
        );
    }
    println!(
        "pose residuals   {:.2} mm, {:.3} deg RMS",
        r.residual_rms_pos * 1e3,
        r.residual_rms_rot.to_degrees()
    );
    println!(
        "Gauss-Newton     {} iterations{}, {:.3} s",
        r.iterations,
        if r.converged { "" } else { " (not converged)" },
        fit_time.as_secs_f64()
    );
    println!("wrote            {} ({} rows)", a.out.display(), rows.len());
    Ok(())
}
