//! The pieces of physics the plain model leaves out, their forms and parameters.

/// A piece of physics the plain Bouc-Wen model leaves out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Effect {
    Delay,
    InputLag,
    Saturation,
    Asymmetry,
    RateDependence,
    Creep,
    Dynamics,
    OffsetDrift,
}

impl Effect {
    /// Every effect, in chain order.
    pub const ALL: [Effect; 8] = [
        Effect::Delay,
        Effect::InputLag,
        Effect::Saturation,
        Effect::Asymmetry,
        Effect::RateDependence,
        Effect::Creep,
        Effect::Dynamics,
        Effect::OffsetDrift,
    ];

    /// The name used in reports and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Delay => "delay",
            Effect::InputLag => "input-lag",
            Effect::Saturation => "saturation",
            Effect::Asymmetry => "asymmetry",
            Effect::RateDependence => "rate-dependence",
            Effect::Creep => "creep",
            Effect::Dynamics => "dynamics",
            Effect::OffsetDrift => "offset-drift",
        }
    }

    /// The effect named `name`, if any.
    pub fn parse(name: &str) -> Option<Effect> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    /// One line on what the effect is, for reports.
    pub fn meaning(self) -> &'static str {
        match self {
            Effect::Delay => "transport delay between command and displacement",
            Effect::InputLag => "first-order low-pass on the drive (amplifier bandwidth)",
            Effect::Saturation => "drive clipped at large |u|",
            Effect::Asymmetry => "even-order term: unequal gains up and down",
            Effect::RateDependence => {
                "hysteretic slope (loop width) or gain growing with the input rate"
            }
            Effect::Creep => "slow visco-elastic (Kelvin-Voigt) lag after the hysteresis",
            Effect::Dynamics => "second-order structural mode after the hysteresis",
            Effect::OffsetDrift => "sensor offset drifting slowly, uncorrelated with the input",
        }
    }

    /// The functional forms the effect is searched in, the first the default. One name
    /// covers several forms because physics offers several (a soft saturation is not a
    /// clip; thermal settling is not a polynomial in time).
    pub fn forms(self) -> &'static [Form] {
        match self {
            Effect::Delay => &[Form::Transport],
            Effect::InputLag => &[Form::FirstOrder, Form::SecondOrder],
            Effect::Saturation => &[Form::Hard, Form::Smooth, Form::Cubic],
            Effect::Asymmetry => &[Form::Even, Form::Direction],
            Effect::RateDependence => &[Form::Width, Form::Gain],
            Effect::Creep => &[Form::KelvinVoigt, Form::Logarithmic],
            Effect::Dynamics => &[Form::OneMode, Form::TwoModes],
            Effect::OffsetDrift => &[Form::Polynomial, Form::Spline, Form::Settling],
        }
    }

    /// The forms the effect is searched in on a core of `kind` (`None`: Bouc-Wen), the
    /// first the default. On the operator cores an asymmetry is the drive warped before the
    /// operators (`x + q x²/u_ref`: the generalised PI's input function, whose linear play
    /// carries the asymmetric PI's quadratic term); the direction form acts on Bouc-Wen's
    /// slope, which plays do not have. The rate-dependent PI scales its weights (gain) or
    /// its thresholds (width) with the low-passed rate; a Preisach plane, defined without a
    /// rate, takes the weights' form only.
    pub fn forms_on(self, kind: Option<super::CoreKind>) -> &'static [Form] {
        use super::CoreKind::{Plays, Relays};
        match (kind, self) {
            (Some(Plays), Effect::Asymmetry) => &[Form::Even],
            (Some(Relays), Effect::RateDependence) => &[Form::Gain],
            _ => self.forms(),
        }
    }

    /// Why the effect is not searched on a core of `kind` (`None`: it is).
    pub fn not_for_core(self, kind: super::CoreKind) -> Option<&'static str> {
        match (kind, self) {
            (super::CoreKind::Relays, Effect::Asymmetry) => Some(
                "the Preisach weights over the (up, down) threshold plane already make any \
                 asymmetric loop; a Bouc-Wen-style asymmetry on top would duplicate it",
            ),
            _ => None,
        }
    }

    /// Whether the effect belongs to one recording (a sensor's offset drift), refitted on
    /// every record, rather than to the actuator (carried over with the same parameters).
    pub fn per_record(self) -> bool {
        self == Effect::OffsetDrift
    }
}

/// One functional form of an [`Effect`] ([`Effect::forms`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Form {
    /// Delay: a fractional transport delay.
    Transport,
    /// Input lag: first-order low-pass.
    FirstOrder,
    /// Input lag: second-order low-pass (an amplifier with a damped pole pair).
    SecondOrder,
    /// Saturation: the drive clipped.
    Hard,
    /// Saturation: `L tanh(x/L)`.
    Smooth,
    /// Saturation: `x - c x³/u_ref²`.
    Cubic,
    /// Asymmetry: `x + q x²/u_ref`.
    Even,
    /// Asymmetry: the hysteretic slope differs on rising and falling drive.
    Direction,
    /// Rate-dependence: the hysteretic slope inside the Bouc-Wen equation grows with the
    /// rate (the loop widens and keeps that width until the drive moves on).
    Width,
    /// Rate-dependence: the linear gain grows with the rate.
    Gain,
    /// Creep: two Kelvin-Voigt elements, one fast and one slow.
    KelvinVoigt,
    /// Creep: equal weight per decade of time constants (logarithmic creep).
    Logarithmic,
    /// Dynamics: one mode.
    OneMode,
    /// Dynamics: two modes in parallel (modal superposition).
    TwoModes,
    /// Drift: quadratic in time.
    Polynomial,
    /// Drift: a piecewise-linear function of time (knots every few seconds): settling,
    /// wander, anything smooth.
    Spline,
    /// Drift: exponential settling `e^(-t/τ)`, τ shared by the records, the amplitude each
    /// record's own (a sensor warming up). Two parameters where creep needs five: creep
    /// must earn its name by what the input drives, not by its initial-state decays.
    Settling,
}

impl Form {
    /// The name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Form::Transport => "transport",
            Form::FirstOrder => "first-order",
            Form::SecondOrder => "second-order",
            Form::Hard => "hard",
            Form::Smooth => "smooth",
            Form::Cubic => "cubic",
            Form::Even => "even-order",
            Form::Direction => "direction",
            Form::Width => "width",
            Form::Gain => "gain",
            Form::KelvinVoigt => "kelvin-voigt",
            Form::Logarithmic => "logarithmic",
            Form::OneMode => "one-mode",
            Form::TwoModes => "two-modes",
            Form::Polynomial => "polynomial",
            Form::Spline => "spline",
            Form::Settling => "settling",
        }
    }
}

/// One shape parameter: its name, physical bounds and neutral value.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub lower: f64,
    pub upper: f64,
    /// Value at which the parameter's effect vanishes (or a typical start).
    pub neutral: f64,
    /// Which effect it belongs to (`None`: the Bouc-Wen shape).
    pub effect: Option<Effect>,
}

impl ParamSpec {
    /// `10^x` for a log-frequency whose top of range means "off" (no mode, no lag).
    pub(super) fn hz_unless_top(&self, x: f64) -> Option<f64> {
        (x < self.upper - 1e-9).then(|| 10f64.powf(x))
    }
}
