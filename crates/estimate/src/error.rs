//! The crate's single error type.

use thiserror::Error;

/// Everything that can go wrong in `htfid-estimate`.
///
/// Variants carry the numbers that explain them, so a message can be acted upon without a
/// debugger.
#[derive(Debug, Clone, Error)]
#[non_exhaustive]
pub enum Error {
    /// No periodic component stands out of the record's spectrum.
    #[error("no periodic component stands out of the output's spectrum (no peak 30 times above its median); give the period")]
    NoPeriodicComponent,
    /// A record could not be built (the record type's own check, its message kept).
    #[error("record: {reason}")]
    Record {
        /// The record type's message.
        reason: String,
    },
    /// A record holds more than one output; the estimators read one.
    #[error("record has {outputs} outputs; the estimators read one (take it with TimeSeries::output_series)")]
    SeveralOutputs {
        /// Outputs of the record.
        outputs: usize,
    },
    /// A record is too short to be transformed.
    #[error("record has {samples} samples; at least {minimum} are needed")]
    TooShort {
        /// Samples given.
        samples: usize,
        /// Smallest accepted length.
        minimum: usize,
    },
    /// The sample interval is not a positive finite number.
    #[error("sample interval must be finite and > 0 (got {dt})")]
    InvalidTimeStep {
        /// The offending interval, s.
        dt: f64,
    },
    /// The start time is not finite.
    #[error("start time must be finite (got {t_start})")]
    InvalidStartTime {
        /// The offending start time, s.
        t_start: f64,
    },
    /// A sample is NaN or infinite.
    #[error("{signal} sample {index} is not finite ({value})")]
    NonFiniteSample {
        /// `"input"` or `"output"`.
        signal: &'static str,
        /// Sample index.
        index: usize,
        /// The value found.
        value: f64,
    },
    /// The system period is not a positive finite number.
    #[error("period must be finite and > 0 (got {period})")]
    InvalidPeriod {
        /// The offending period, s.
        period: f64,
    },
    /// A record does not span a whole number of system periods.
    #[error(
        "record lasts {duration} s = {ratio} periods of {period} s; it must be a whole number of \
         periods (N*dt = P*T, P integer, to within 1e-6 periods) so that the pumping frequency is \
         exactly P DFT bins"
    )]
    NotWholePeriods {
        /// Record length `N * dt`, s.
        duration: f64,
        /// System period, s.
        period: f64,
        /// `duration / period`.
        ratio: f64,
    },
    /// No records were given.
    #[error("no records given")]
    NoRecords,

    /// An output was given to an estimator prepared from another input.
    #[error(
        "the record's input differs from the one the estimator was prepared from \
         (at sample {index}); prepare it again from this record's input"
    )]
    InputDiffers {
        /// The first sample that differs (or the length, when the lengths differ).
        index: usize,
    },
    /// Records do not share a DFT grid.
    #[error(
        "record {index} has {samples} samples at dt = {dt} s but record 0 has {expected_samples} \
         at dt = {expected_dt} s; all records must share one DFT grid"
    )]
    RecordsDiffer {
        /// Index of the first differing record.
        index: usize,
        /// Its length.
        samples: usize,
        /// Its sample interval, s.
        dt: f64,
        /// Length of record 0.
        expected_samples: usize,
        /// Sample interval of record 0, s.
        expected_dt: f64,
    },
    /// The harmonic list is empty.
    #[error("no harmonics given")]
    NoHarmonics,
    /// A harmonic index appears twice.
    #[error("harmonic {n} is listed twice")]
    DuplicateHarmonic {
        /// The repeated index.
        n: i32,
    },
    /// The frequency band is not an interval.
    #[error("band ({lo}, {hi}) rad/s is invalid: need finite lo < hi")]
    InvalidBand {
        /// Lower edge, rad/s.
        lo: f64,
        /// Upper edge, rad/s.
        hi: f64,
    },
    /// The band holds too few DFT bins.
    #[error(
        "band ({lo}, {hi}) rad/s holds {bins} DFT bins (spacing {spacing} rad/s); at least \
         {minimum} are needed"
    )]
    TooFewBins {
        /// Lower edge, rad/s.
        lo: f64,
        /// Upper edge, rad/s.
        hi: f64,
        /// Bins found.
        bins: usize,
        /// Bin spacing `2 pi / (N dt)`, rad/s.
        spacing: f64,
        /// Bins needed.
        minimum: usize,
    },
    /// An output bin in the band would need input (or output) at or beyond the Nyquist frequency.
    #[error(
        "output at {omega} rad/s with harmonic {n} needs a DFT bin at {needed} rad/s, at or beyond \
         the Nyquist frequency {nyquist} rad/s; narrow the band or sample faster"
    )]
    BeyondNyquist {
        /// Output frequency, rad/s.
        omega: f64,
        /// Harmonic index.
        n: i32,
        /// The frequency that would be needed, rad/s.
        needed: f64,
        /// `pi / dt`, rad/s.
        nyquist: f64,
    },
    /// Fewer records than harmonics, without regularisation.
    #[error(
        "{records} records cannot separate {harmonics} harmonics bin by bin; use at least as many \
         records as harmonics, or ridge/smoothness regularisation"
    )]
    TooFewRecords {
        /// Records given.
        records: usize,
        /// Harmonics requested.
        harmonics: usize,
    },
    /// A regularisation weight is negative or not finite.
    #[error("regularisation weight must be finite and >= 0 (got {alpha})")]
    InvalidAlpha {
        /// The offending weight.
        alpha: f64,
    },
    /// The input has no power at any bin the estimator reads.
    #[error("the input has no power at the bins the band needs; nothing can be estimated")]
    NoExcitation,
    /// The banded normal matrix lost positive definiteness.
    #[error(
        "normal matrix is not positive definite at unknown {index} (pivot {pivot}); the data do \
         not determine the estimate: with a small alpha, increase it or the number of records; \
         an alpha far above 1 drowns the data in the smoothness penalty, lower it"
    )]
    NotPositiveDefinite {
        /// Unknown (row) index where the Cholesky pivot failed.
        index: usize,
        /// The pivot value.
        pivot: f64,
    },
    /// Generalised cross-validation found no usable weight.
    #[error("generalised cross-validation failed at every weight on the grid 1e-8..1e4")]
    GcvFailed,
    /// Generalised cross-validation's score kept falling to the smallest weight it tries: the
    /// data do not choose a smoothing, and the estimate at that weight interpolates them (its
    /// residual, and so its standard errors, near zero while its real error is not). It happens
    /// where a single record carries more harmonics per frequency bin than the smoothing can
    /// separate.
    #[error(
        "generalised cross-validation chose the smallest weight it tries ({alpha:e}), where the \
         estimate interpolates the data ({dof:.1} residual degrees of freedom of {data:.0} \
         data) and its standard errors mean nothing; give the smoothness weight a value \
         (for example 1), or estimate from more records or fewer harmonics"
    )]
    GcvAtSmallestWeight {
        /// The weight (dimensionless).
        alpha: f64,
        /// Residual degrees of freedom at it.
        dof: f64,
        /// Complex data.
        data: f64,
    },
    /// An option is out of range.
    #[error("option {name} = {value} is invalid: {reason}")]
    InvalidOption {
        /// Option name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is required.
        reason: &'static str,
    },
    /// The local polynomial model has no residual degrees of freedom.
    #[error(
        "local polynomial window gives {equations} independent equations for {unknowns} unknowns \
         per bin; widen the window, lower the degree or add records"
    )]
    LpmUnderdetermined {
        /// Independent equations per bin after removing the transient.
        equations: usize,
        /// Unknowns per bin.
        unknowns: usize,
    },
    /// LPM was combined with across-bin regularisation.
    #[error(
        "the local polynomial method cannot be combined with ridge or smoothness regularisation"
    )]
    LpmWithRegularisation,
    /// A multisine period is not a whole number of system periods.
    #[error(
        "multisine period {multisine_period} s is {ratio} system periods of {period} s; it must be \
         a whole number"
    )]
    MultisineNotWholePeriods {
        /// Multisine period, s.
        multisine_period: f64,
        /// System period, s.
        period: f64,
        /// Their ratio.
        ratio: f64,
    },
    /// A multisine period is not a whole number of samples.
    #[error(
        "multisine period {} s is {} samples of {} s ({} Hz); it must be a whole number: choose \
         a sample rate that gives a whole number of samples per forcing period",
        short(*multisine_period),
        short(*ratio),
        short(*dt),
        short(1.0 / *dt)
    )]
    MultisineNotWholeSamples {
        /// Multisine period, s.
        multisine_period: f64,
        /// Sample interval, s.
        dt: f64,
        /// Their ratio.
        ratio: f64,
    },
    /// A record is not a whole number of multisine periods.
    #[error(
        "record of {samples} samples is not a whole number of multisine periods of \
         {period_samples} samples"
    )]
    NotWholeMultisinePeriods {
        /// Record length.
        samples: usize,
        /// Samples per multisine period.
        period_samples: usize,
    },
    /// The plus and minus records of a sign-reversed pair start at different orbit phases.
    #[error(
        "the minus record starts at {minus_start} s and the plus record at {plus_start} s: \
         they must differ by a whole number of periods ({period} s)"
    )]
    PairPhaseMismatch {
        /// Start of the plus record, s.
        plus_start: f64,
        /// Start of the minus record, s.
        minus_start: f64,
        /// The period, s.
        period: f64,
    },
    /// Too few multisine periods for a scatter-based standard error.
    #[error("record holds {periods} multisine periods; at least {minimum} are needed")]
    TooFewPeriods {
        /// Periods found.
        periods: usize,
        /// Periods needed.
        minimum: usize,
    },
    /// A line index is zero or at/above the Nyquist bin.
    #[error("line {line} is invalid: lines must be >= 1 and below the Nyquist bin {nyquist_bin}")]
    InvalidLine {
        /// The line (DFT bin of one multisine period).
        line: usize,
        /// Half the samples per multisine period.
        nyquist_bin: usize,
    },
    /// The same line appears twice.
    #[error("line {line} is listed twice")]
    DuplicateLine {
        /// The repeated line.
        line: usize,
    },
    /// Two (line, harmonic) pairs land on one output bin.
    #[error(
        "output bin {bin} receives line {line_a} through harmonic {n_a} and line {line_b} through \
         harmonic {n_b} (negative lines are mirror images); choose lines that do not collide"
    )]
    LineCollision {
        /// Output bin (of one multisine period).
        bin: i64,
        /// First signed line.
        line_a: i64,
        /// Its harmonic.
        n_a: i32,
        /// Second signed line.
        line_b: i64,
        /// Its harmonic.
        n_b: i32,
    },
    /// A line carries no input power.
    #[error("line {line} carries no input power (|U| = {magnitude}, largest input bin {largest})")]
    LineNotExcited {
        /// The line.
        line: usize,
        /// Its input magnitude.
        magnitude: f64,
        /// The largest input bin magnitude.
        largest: f64,
    },
    /// Two records that must pair do not match.
    #[error(
        "paired records differ: {plus_samples} samples at dt = {plus_dt} s versus {minus_samples} \
         at dt = {minus_dt} s"
    )]
    PairMismatch {
        /// Length of the `+u` record.
        plus_samples: usize,
        /// Its sample interval, s.
        plus_dt: f64,
        /// Length of the `-u` record.
        minus_samples: usize,
        /// Its sample interval, s.
        minus_dt: f64,
    },
    /// Arrays handed to [`HtfEstimate::new`](crate::HtfEstimate::new) disagree.
    #[error("estimate arrays are inconsistent: {what} has length {found}, expected {expected}")]
    InconsistentEstimate {
        /// Which array.
        what: &'static str,
        /// Its length.
        found: usize,
        /// The length implied by the others.
        expected: usize,
    },
    /// Levenberg-Marquardt needs parameters and residuals.
    #[error(
        "Levenberg-Marquardt needs at least one parameter and one residual (got {parameters} \
         parameters and {residuals} residuals)"
    )]
    LmDimensions {
        /// Parameters.
        parameters: usize,
        /// Residuals.
        residuals: usize,
    },
    /// An option vector has the wrong length.
    #[error("{what} has length {found}, expected {expected}")]
    WrongLength {
        /// Which vector.
        what: &'static str,
        /// Its length.
        found: usize,
        /// Required length.
        expected: usize,
    },
    /// A parameter bound pair is not an interval.
    #[error(
        "parameter {index}: bounds [{lower}, {upper}] are invalid (need lower <= upper, no NaN)"
    )]
    InvalidBounds {
        /// Parameter index.
        index: usize,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
    },
    /// A start value is not finite or lies outside its bounds.
    #[error(
        "parameter {index}: start value {value} is not finite or lies outside [{lower}, {upper}]"
    )]
    InvalidStart {
        /// Parameter index.
        index: usize,
        /// Start value.
        value: f64,
        /// Lower bound.
        lower: f64,
        /// Upper bound.
        upper: f64,
    },
    /// The residual function reported an error at the start point.
    #[error("residual function failed at the start point: {message}")]
    ResidualFailed {
        /// The function's own message.
        message: String,
    },
    /// A residual is not finite at the start point.
    #[error("residual {index} is not finite ({value}) at the start point")]
    NonFiniteResidual {
        /// Residual index.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// The finite-difference Jacobian could not be formed for a parameter.
    #[error(
        "finite-difference Jacobian failed for parameter {index}: the residual function failed or \
         was not finite on both sides of {value}"
    )]
    JacobianFailed {
        /// Parameter index.
        index: usize,
        /// Parameter value at which the difference was attempted.
        value: f64,
    },
    /// The caller's Jacobian (see `levenberg_marquardt_with_jacobian`) failed or was not
    /// finite.
    #[error("the Jacobian could not be computed: {message}")]
    JacobianFunction {
        /// What failed.
        message: String,
    },
    /// An estimator needs a part of the experiment's layout that it lacks.
    #[error("the {estimator} estimator needs {needs}; the experiment has none")]
    MissingLayout {
        /// The estimator's name.
        estimator: &'static str,
        /// What it needs.
        needs: &'static str,
    },
    /// A chirp train's copy is shorter than one period.
    #[error("each copy lasts {duration} s, shorter than one period of {period} s")]
    CopyShorterThanPeriod {
        /// A copy's length, s.
        duration: f64,
        /// The period, s.
        period: f64,
    },
    /// A window's length is not a whole number of samples.
    #[error(
        "a window of {} s is not a whole number of samples of {} s ({} Hz): choose a sample \
         rate that gives a whole number of samples per forcing period",
        short(*duration),
        short(*dt),
        short(1.0 / *dt)
    )]
    WindowNotWholeSamples {
        /// The window's length, s.
        duration: f64,
        /// Sample interval, s.
        dt: f64,
    },
    /// A window runs past the sampled signal (or input and output differ in length).
    #[error("the window [{start}, {end}) s runs past the signal, which ends at {signal_end} s")]
    WindowOutsideSignal {
        /// Window start, s.
        start: f64,
        /// Window end, s.
        end: f64,
        /// End of the signal, s.
        signal_end: f64,
    },
    /// The Jacobian of a fit is rank deficient: its parameters are not identified, so no
    /// covariance (and no uncertainty budget) exists.
    #[error(
        "the fit's Jacobian is rank deficient ({parameters} parameters): no covariance exists"
    )]
    SingularCovariance {
        /// Parameters fitted.
        parameters: usize,
    },
}

/// Shorthand for results of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// `x` to ten significant digits, shown without trailing zeros (`127.19999999999999` reads
/// `127.2`).
fn short(x: f64) -> f64 {
    format!("{x:.9e}").parse().unwrap_or(x)
}
