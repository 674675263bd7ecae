//! A DVL log summarised for people and programs: what `dvlcal dvl-info` prints.

use std::fmt::Write as _;

use serde_json::json;

use super::log::DvlLog;

/// Mean, standard deviation, minimum and maximum of a series.
fn moments(x: impl Iterator<Item = f64> + Clone) -> serde_json::Value {
    let n = x.clone().count();
    if n == 0 {
        return serde_json::Value::Null;
    }
    let mean = x.clone().sum::<f64>() / n as f64;
    let var = x.clone().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    let min = x.clone().fold(f64::INFINITY, f64::min);
    let max = x.fold(f64::NEG_INFINITY, f64::max);
    json!({"mean": mean, "std": var.sqrt(), "min": min, "max": max})
}

impl DvlLog {
    /// What the log holds, as one JSON object (`dvlcal dvl-info --json`): format, counts, time
    /// span, rate, velocity statistics, rejected lines and time problems with their lines.
    pub fn summary_json(&self) -> serde_json::Value {
        summary_json(self)
    }

    /// The same as text, one item a line (`dvlcal dvl-info`).
    pub fn summary_text(&self) -> String {
        summary_text(self, &summary_json(self))
    }
}

fn summary_json(log: &DvlLog) -> serde_json::Value {
    let s = &log.stats;
    let file = s.path.display().to_string();
    let n = log.samples.len();
    let axis = |k: usize| moments(log.samples.iter().map(move |x| x.v[k]));
    let abs = |t: Option<f64>| t.map(|t| log.epoch.format_abs(t, 6));
    let mut v = json!({
        "file": file,
        "format": s.format.map(|f| f.name()),
        "formats_seen": s.formats_seen,
        "topic": s.topic,
        "time_source": s.time_source.name(),
        "time_source_used": s.time_source_used,
        "epoch_s": log.epoch.sec,
        "lines": s.lines,
        "velocity_reports": s.velocity_reports,
        "valid": s.valid,
        "invalid": s.invalid,
        "duplicates": s.duplicates,
        "samples": n,
        "water_velocity_reports": s.water_velocity_reports,
        "other_reports": s.other_reports,
        "other_by_type": s.other_by_type,
        "rejected_lines": s.rejected_lines,
        "rejected_by_reason": s.rejected_by_reason,
        "rejected": s.rejected.iter().map(|r| json!({
            "at": s.at(r.line), "line": r.line, "reason": r.reason, "detail": r.detail
        })).collect::<Vec<_>>(),
        "time_backwards": s.time_backwards,
        "time_repeats": s.time_repeats,
        "time_problems": s.time_problems.iter().map(|p| json!({
            "at": s.at(p.line), "line": p.line, "step_s": p.step_s
        })).collect::<Vec<_>>(),
        "warnings": s.warnings,
        "first_time_s": s.first_time_s,
        "last_time_s": s.last_time_s,
        "first_time_abs": abs(s.first_time_s),
        "last_time_abs": abs(s.last_time_s),
        "span_s": s.first_time_s.zip(s.last_time_s).map(|(a, b)| b - a),
        "rate_hz": s.rate_hz(n),
        "velocity": {
            "vx": axis(0), "vy": axis(1), "vz": axis(2),
            "speed": moments(log.samples.iter().map(|x| x.v.norm())),
        },
        "with_covariance": log.samples.iter().filter(|x| x.cov.is_some()).count(),
        "gap_threshold_s": log.gap_threshold_s(),
        "gaps": log.gaps(log.gap_threshold_s()).iter().map(|g| json!({
            "start_s": g.start_s, "end_s": g.end_s, "length_s": g.end_s - g.start_s,
            "start_abs": log.epoch.format_abs(g.start_s, 6),
            "at": s.at(g.lines.0), "lines": [g.lines.0, g.lines.1],
        })).collect::<Vec<_>>(),
    });
    // (Apart from the object above, whose size reaches the macro's recursion limit.)
    v["polled_capture"] = serde_json::to_value(&s.polled).unwrap_or_default();
    v
}

fn summary_text(log: &DvlLog, v: &serde_json::Value) -> String {
    let mut o = String::new();
    let s = &log.stats;
    let file = s.path.display();
    let _ = writeln!(o, "{file}");
    let _ = writeln!(
        o,
        "  format            {}",
        s.format.map(|f| f.name()).unwrap_or("?")
    );
    for (label, n) in &s.formats_seen {
        let _ = writeln!(o, "    {label}: {n} reports");
    }
    if let Some(t) = &s.topic {
        let _ = writeln!(o, "  topic             {t}");
    }
    let _ = writeln!(o, "  time source       {}", s.time_source_used);
    let _ = writeln!(o, "  {:<18}{}", format!("{}s", s.unit()), s.lines);
    let _ = writeln!(
        o,
        "  velocity reports  {} (valid {}, invalid {}, duplicates {})",
        s.velocity_reports, s.valid, s.invalid, s.duplicates
    );
    let _ = writeln!(o, "  samples used      {}", log.samples.len());
    if s.water_velocity_reports > 0 {
        let _ = writeln!(o, "  water-track       {}", s.water_velocity_reports);
    }
    let _ = writeln!(o, "  other reports     {}", s.other_reports);
    for (k, n) in &s.other_by_type {
        let _ = writeln!(o, "    {k}: {n}");
    }
    if let (Some(a), Some(b)) = (s.first_time_s, s.last_time_s) {
        let _ = writeln!(
            o,
            "  time span         {} .. {} ({:.3} s)",
            log.epoch.format_abs(a, 6),
            log.epoch.format_abs(b, 6),
            b - a
        );
    }
    if let Some(r) = s.rate_hz(log.samples.len()) {
        let _ = writeln!(o, "  mean rate         {r:.3} Hz");
    }
    let threshold = log.gap_threshold_s();
    let gaps = log.gaps(threshold);
    if !gaps.is_empty() {
        let total: f64 = gaps.iter().map(|g| g.end_s - g.start_s).sum();
        let _ = writeln!(
            o,
            "  gaps              {} without a valid report for {threshold:.2} s or more ({total:.1} s in all)",
            gaps.len()
        );
        for g in gaps.iter().take(10) {
            let _ = writeln!(
                o,
                "    {}: {:.3} s from {}",
                s.at_range(g.lines.0, g.lines.1),
                g.end_s - g.start_s,
                log.epoch.format_abs(g.start_s, 3)
            );
        }
        if gaps.len() > 10 {
            let _ = writeln!(o, "    ... {} more", gaps.len() - 10);
        }
    }
    for k in ["vx", "vy", "vz", "speed"] {
        let m = &v["velocity"][k];
        if m.is_object() {
            let _ = writeln!(
                o,
                "  {k:<6} m/s        mean {:+.4}  std {:.4}  min {:+.4}  max {:+.4}",
                m["mean"].as_f64().unwrap_or(f64::NAN),
                m["std"].as_f64().unwrap_or(f64::NAN),
                m["min"].as_f64().unwrap_or(f64::NAN),
                m["max"].as_f64().unwrap_or(f64::NAN)
            );
        }
    }
    let _ = writeln!(
        o,
        "  {:<18}{}",
        format!("rejected {}s", s.unit()),
        s.rejected_lines
    );
    for (reason, n) in &s.rejected_by_reason {
        let _ = writeln!(o, "    {reason}: {n}");
    }
    for r in &s.rejected {
        let _ = writeln!(o, "    {}: {}: {}", s.at(r.line), r.reason, r.detail);
    }
    if s.rejected_lines > s.rejected.len() {
        let _ = writeln!(o, "    ... {} more", s.rejected_lines - s.rejected.len());
    }
    if s.time_backwards + s.time_repeats > 0 {
        let _ = writeln!(
            o,
            "  time problems     {} backwards, {} repeated",
            s.time_backwards, s.time_repeats
        );
        for p in &s.time_problems {
            let _ = writeln!(o, "    {}: step {:+.6} s", s.at(p.line), p.step_s);
        }
    }
    for w in &s.warnings {
        let _ = writeln!(o, "  warning: {w}");
    }
    o
}
