//! Priors on the calibration: a measured lever arm keeps a weakly observed one in place without
//! disturbing the rest, and a prior acts as a factor of the MAP problem (it pulls the estimate
//! and shrinks the covariance by the information it carries).

use dvlcal::calib::model::difference;
use dvlcal::calib::prior::{LeverArmPrior, Priors, RotationPrior};
use dvlcal::calib::{CalibOptions, DeterminedBy, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};

fn with_priors(priors: Priors) -> CalibOptions {
    CalibOptions {
        priors,
        ..CalibOptions::default()
    }
}

#[test]
fn a_measured_lever_arm_holds_a_weak_one_without_disturbing_the_rest() {
    let ds = simulate(&SimConfig {
        seed: 8,
        duration_s: 60.0,
        motion: MotionKind::WeakRotation,
        ..SimConfig::default()
    })
    .expect("simulation");
    let free = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("no prior");
    let sigma = 0.01;
    let prior = Priors {
        lever_arm: Some(LeverArmPrior {
            lever_arm_cam_m: ds.truth.lever_arm_cam_m(),
            sigma_m: sigma,
        }),
        ..Priors::default()
    };
    let held = calibrate(&ds.poses, &ds.dvl, &with_priors(prior)).expect("with prior");
    let lever_std = |o: &dvlcal::calib::CalibrationOutcome| o.std.lever_arm_m.max();
    assert!(
        !held.warnings.iter().any(|w| w.contains("disagree")),
        "{:?}",
        held.warnings
    );
    assert!(
        held.warnings
            .iter()
            .any(|w| w.contains("lever arm comes mainly from its prior")),
        "{:?}",
        held.warnings
    );
    // The lever arm is labelled as the prior's, the rotation as the data's.
    assert_eq!(held.verdicts.lever_arm.by, DeterminedBy::Prior);
    assert_eq!(held.verdicts.rotation.by, DeterminedBy::Data);
    // The motion alone leaves the lever arm loose; the prior bounds it by its own sigma.
    assert!(lever_std(&free) > sigma, "{:?}", free.std);
    assert!(lever_std(&held) < sigma, "{:?}", held.std);
    // Information adds: on each axis the held std is that of the data and the prior combined.
    for k in 0..3 {
        let f = free.std.lever_arm_m[k];
        let combined = 1.0 / (1.0 / (f * f) + 1.0 / (sigma * sigma)).sqrt();
        let h = held.std.lever_arm_m[k];
        assert!(
            (h / combined - 1.0).abs() < 0.05,
            "axis {k}: {h} vs {combined}"
        );
    }
    let d = difference(&held.params, &ds.truth);
    let std = held.covariance.diagonal().map(f64::sqrt);
    for k in 0..8 {
        assert!(
            d[k].abs() < 4.0 * std[k],
            "parameter {k}: error {} vs std {}",
            d[k],
            std[k]
        );
    }
}

#[test]
fn a_prior_pulls_the_estimate_and_adds_its_information() {
    let ds = simulate(&SimConfig {
        seed: 9,
        duration_s: 60.0,
        ..SimConfig::default()
    })
    .expect("simulation");
    let data = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("no prior");
    // A tight prior 5 cm off on x: the estimate moves to it, the data's lever arm being far
    // looser than 0.1 mm.
    let mut off = ds.truth.lever_arm_cam_m();
    off.x += 0.05;
    let tight = Priors {
        lever_arm: Some(LeverArmPrior {
            lever_arm_cam_m: off,
            sigma_m: 1e-4,
        }),
        ..Priors::default()
    };
    let pulled = calibrate(&ds.poses, &ds.dvl, &with_priors(tight)).expect("tight prior");
    assert!(
        pulled
            .warnings
            .iter()
            .any(|w| w.contains("mainly from its prior"))
    );
    assert!(
        (pulled.params.lever_arm_cam_m() - off).norm() < 1e-3,
        "{:?} vs {off:?}",
        pulled.params.lever_arm_cam_m()
    );
    // A rotation prior at the truth with the data's own std adds as much information as the
    // data along the worst axis: its std shrinks by about 1/sqrt(2).
    let s = data.std.rotation_deg.max();
    let r = Priors {
        rotation: Some(RotationPrior {
            r_cam_dvl: ds.truth.r_dvl_cam().transpose(),
            sigma_deg: s,
        }),
        ..Priors::default()
    };
    let both = calibrate(&ds.poses, &ds.dvl, &with_priors(r)).expect("rotation prior");
    let ratio = both.std.rotation_deg.max() / s;
    // Equal information: neither is "mainly" the prior.
    assert!(
        both.warnings
            .iter()
            .any(|w| w.contains("rotation comes mainly from the data"))
    );
    assert!(ratio < 0.85 && ratio > 0.5, "{ratio}");
    // Bad priors are refused before anything is computed.
    let bad = Priors {
        lever_arm: Some(LeverArmPrior {
            lever_arm_cam_m: off,
            sigma_m: 0.0,
        }),
        ..Priors::default()
    };
    let e = calibrate(&ds.poses, &ds.dvl, &with_priors(bad))
        .unwrap_err()
        .to_string();
    assert!(e.contains("lever-arm prior"), "{e}");
}

#[test]
fn priors_from_the_command_line() {
    let dir = std::env::temp_dir().join(format!("dvlcal-priors-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let req = dvlcal::pipeline::SimulateRequest {
        config: SimConfig {
            seed: 4,
            duration_s: 40.0,
            ..SimConfig::default()
        },
        images: None,
        note: String::new(),
    };
    dvlcal::pipeline::write_simulated_dataset(&dir, &req, &|_, _| {}).expect("simulate");
    let exe = env!("CARGO_BIN_EXE_dvlcal");
    let run = |args: &[&str]| {
        std::process::Command::new(exe)
            .arg("calibrate")
            .arg(&dir)
            .args(args)
            .output()
            .expect("run dvlcal")
    };
    let out = run(&[
        "--out",
        dir.join("out").to_str().unwrap(),
        "--lever-arm-prior",
        "-0.1,0.05,0.2:0.0001",
        "--rotation-prior=0,0,90",
    ]);
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(
        text.contains("lever arm comes mainly from its prior"),
        "{text}"
    );
    assert!(text.contains("rotation comes mainly from"), "{text}");
    for bad in ["0.1,0.2", "0.1,0.2,0.3:-1", "a,b,c"] {
        let out = run(&[
            "--out",
            dir.join("bad").to_str().unwrap(),
            "--lever-arm-prior",
            bad,
        ]);
        assert!(!out.status.success());
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(e.contains("--lever-arm-prior") && e.contains(bad), "{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
