//! The words for the estimator's settings in its messages and errors.
//!
//! The library names a setting by its field in the option structs; a program whose users know
//! the settings by other names (command-line flags) gives its own words through
//! [`super::CalibOptions::names`]. The messages never spell a program's flags themselves.

/// A setting that the estimator's messages and errors point the user to.
///
/// The library words them by their fields ([`Setting::field`]: `dvl_sigma`,
/// `priors.lever_arm`); a program whose users know the settings by other names (command-line
/// flags) gives its own words through [`super::CalibOptions::names`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Setting {
    /// `CalibOptions::dvl_sigma`.
    DvlSigma,
    /// `CalibOptions::default_dvl_sigma`.
    DefaultDvlSigma,
    /// `CalibOptions::default_lever_arm_sigma_m`.
    DefaultLeverArmSigma,
    /// The lever-arm prior, `priors.lever_arm`.
    LeverArmPrior,
    /// The rotation prior, `priors.rotation`.
    RotationPrior,
    /// The offsets allowed, `offset.range`.
    OffsetRange,
    /// The half-width of the fine offset search, `offset.window_s`.
    OffsetWindow,
    /// The coarse offset search's step, `offset.coarse_step`.
    OffsetCoarseStep,
    /// The global clock alignment's grid step, `offset.align.step_s`.
    AlignStep,
    /// The loss, `CalibOptions::loss`.
    Loss,
    /// The least-squares loss, `loss` set to `Loss::L2`.
    LeastSquares,
    /// UIC, `method` set to `Method::Uic`.
    Uic,
    /// Refinement from a guess, `method` set to `Method::Bcd`.
    RefineGuess,
    /// Fixed extrinsics with the clock offset estimated, `Method::Fixed`'s `estimate_offset`.
    EstimateOffset,
    /// The guess of `Method::Bcd` or `Method::Fixed`.
    Guess,
    /// The clock drift's estimate, `CalibOptions::clock_drift`.
    ClockDrift,
}

impl Setting {
    /// Every setting, for tables that name each of them.
    pub const ALL: [Setting; 16] = [
        Setting::DvlSigma,
        Setting::DefaultDvlSigma,
        Setting::DefaultLeverArmSigma,
        Setting::LeverArmPrior,
        Setting::RotationPrior,
        Setting::OffsetRange,
        Setting::OffsetWindow,
        Setting::OffsetCoarseStep,
        Setting::AlignStep,
        Setting::Loss,
        Setting::LeastSquares,
        Setting::Uic,
        Setting::RefineGuess,
        Setting::EstimateOffset,
        Setting::Guess,
        Setting::ClockDrift,
    ];

    /// The setting as the library's option structs name it.
    pub fn field(self) -> &'static str {
        match self {
            Setting::DvlSigma => "dvl_sigma",
            Setting::DefaultDvlSigma => "default_dvl_sigma",
            Setting::DefaultLeverArmSigma => "default_lever_arm_sigma_m",
            Setting::LeverArmPrior => "priors.lever_arm",
            Setting::RotationPrior => "priors.rotation",
            Setting::OffsetRange => "offset.range",
            Setting::OffsetWindow => "offset.window_s",
            Setting::OffsetCoarseStep => "offset.coarse_step",
            Setting::AlignStep => "offset.align.step_s",
            Setting::Loss => "loss",
            Setting::LeastSquares => "loss Loss::L2",
            Setting::Uic => "method Method::Uic",
            Setting::RefineGuess => "method Method::Bcd with a guess",
            Setting::EstimateOffset => "Method::Fixed's estimate_offset",
            Setting::Guess => "the method's guess",
            Setting::ClockDrift => "clock_drift",
        }
    }

    /// The setting whose [`Setting::field`] is `field`.
    pub fn from_field(field: &str) -> Option<Setting> {
        Setting::ALL.into_iter().find(|s| s.field() == field)
    }
}

/// How messages name the settings: a function from each setting to its words.
pub type SettingNames = fn(Setting) -> &'static str;
