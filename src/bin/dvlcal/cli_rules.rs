//! The rules every option of the command line keeps, checked on the parser itself: numeric
//! options take negative values (`-0.5`, `-0.5,0.5`), a default is shown in a form the parser
//! takes, and an option taking fractional numbers states its unit. Numbers are parsed by typed
//! value parsers; an option is tried with values, not recognised by its declaration.

use clap::error::ErrorKind;

/// Each subcommand with its arguments no longer required (so that one option parses alone).
fn subcommands() -> Vec<clap::Command> {
    crate::command()
        .get_subcommands()
        .map(|sub| {
            let mut c = sub.clone().mut_args(|a| a.required(false));
            let groups: Vec<String> = c.get_groups().map(|g| g.get_id().to_string()).collect();
            for g in groups {
                c = c.mut_group(g, |g| g.required(false));
            }
            c
        })
        .collect()
}

/// The error kind of parsing `--long value` alone (`None`: parsed, or only something else was
/// missing).
fn parse_one(sub: &clap::Command, long: &str, value: &str) -> Option<ErrorKind> {
    let args = [sub.get_name(), &format!("--{long}"), value];
    match sub.clone().try_get_matches_from(args) {
        Ok(_) => None,
        Err(e) => match e.kind() {
            ErrorKind::MissingRequiredArgument => None,
            k => Some(k),
        },
    }
}

fn rejects_value(sub: &clap::Command, long: &str, value: &str) -> bool {
    matches!(
        parse_one(sub, long, value),
        Some(ErrorKind::InvalidValue | ErrorKind::ValueValidation)
    )
}

/// Every option that takes a value: (subcommand, option, its long name).
fn options() -> Vec<(clap::Command, clap::Arg, String)> {
    let mut out = Vec::new();
    for sub in subcommands() {
        for a in sub.get_arguments() {
            let takes_value = a.get_action().takes_values();
            if let (Some(long), false, true) = (a.get_long(), a.is_positional(), takes_value) {
                out.push((sub.clone(), a.clone(), long.to_string()));
            }
        }
    }
    out
}

/// A text or path option takes anything; a numeric one takes `1` or `1,1,1` and refuses `x`.
fn takes_numbers(sub: &clap::Command, long: &str) -> bool {
    rejects_value(sub, long, "x") && ["1", "1,1,1"].iter().any(|v| !rejects_value(sub, long, v))
}

#[test]
fn every_numeric_option_takes_a_leading_minus() {
    let mut numeric = 0;
    let mut refused = Vec::new();
    for (sub, _, long) in options() {
        if !takes_numbers(&sub, &long) {
            continue;
        }
        numeric += 1;
        for v in ["-1", "-1,1", "-0.5,0.5,-1"] {
            if parse_one(&sub, &long, v) == Some(ErrorKind::UnknownArgument) {
                refused.push(format!("{} --{long} {v}", sub.get_name()));
            }
        }
    }
    assert!(numeric >= 40, "only {numeric} numeric options found");
    assert!(refused.is_empty(), "refused: {refused:#?}");
}

#[test]
fn every_default_is_shown_as_the_parser_takes_it() {
    let mut bad = Vec::new();
    for (sub, a, long) in options() {
        let d = a.get_default_values();
        if d.is_empty() {
            continue;
        }
        // The help shows several defaults joined by spaces.
        let shown = d
            .iter()
            .map(|v| v.to_string_lossy())
            .collect::<Vec<_>>()
            .join(" ");
        if parse_one(&sub, &long, &shown).is_some() {
            bad.push(format!("{} --{long} [default: {shown}]", sub.get_name()));
        }
    }
    assert!(bad.is_empty(), "defaults the parser refuses: {bad:#?}");
}

/// Units as the help texts write them.
const UNITS: [&str; 17] = [
    "s",
    "seconds",
    "ms",
    "milliseconds",
    "m",
    "metres",
    "mm",
    "m/s",
    "rad",
    "radians",
    "rad/s",
    "deg",
    "degrees",
    "px",
    "pixels",
    "hz",
    "ppm",
];

#[test]
fn every_fractional_option_states_its_unit() {
    let mut missing = Vec::new();
    for (sub, a, long) in options() {
        // Whole-number options are counts; fractional ones have a unit or say they have none.
        if !takes_numbers(&sub, &long) || rejects_value(&sub, &long, "0.5") {
            continue;
        }
        let help = a.get_long_help().or(a.get_help()).map(|h| h.to_string());
        let help = help.unwrap_or_default().to_lowercase().replace("'s", "");
        let unit = help
            .split(|c: char| !(c.is_alphanumeric() || c == '/'))
            .any(|w| UNITS.contains(&w));
        if !(unit || help.contains("no unit")) {
            missing.push(format!("{} --{long}: {help}", sub.get_name()));
        }
    }
    assert!(missing.is_empty(), "no unit stated: {missing:#?}");
}
