/// Errors of the diagnosis. Every variant carries the numbers that explain it.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The record is too short to diagnose.
    #[error("a record needs at least {min} samples (got {found})")]
    TooShort {
        /// Smallest accepted length.
        min: usize,
        /// Length given.
        found: usize,
    },
    /// The data's HTFs could not be compared with the models' (too few excited periods, a
    /// forcing period that is no whole number of samples, a model without a limit cycle).
    #[error("the data's HTFs cannot be compared with the models': {reason}")]
    Htf {
        /// What failed.
        reason: String,
    },
    /// A list of parameter names holds one it may not.
    #[error("{option} cannot hold \"{parameter}\": it must list {expected}")]
    InvalidParameterName {
        /// The option (a field of the options).
        option: &'static str,
        /// The name given.
        parameter: String,
        /// What the list must hold.
        expected: &'static str,
    },
    /// An option is out of range.
    #[error("{name} must be {expected} (got {value})")]
    InvalidOption {
        /// Option name as in [`ModelFitOptions`](crate::ModelFitOptions).
        name: &'static str,
        /// What was expected.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
    /// The measured output does not change over a range: a record without motion says
    /// nothing about the dynamics, and every normalised error of it divides by zero.
    #[error(
        "the measured output is constant ({value}) over the {which} samples {start}..{end}: a \
         record without motion says nothing about the dynamics; check the output column and \
         that the system was excited"
    )]
    ConstantOutput {
        /// The output's name.
        which: String,
        /// First sample.
        start: usize,
        /// Last sample (exclusive).
        end: usize,
        /// The constant value.
        value: f64,
    },
    /// The limit cycle a diagnosis starts the record on cannot be found at the
    /// diagnosis's integrator tolerance.
    #[error(
        "the model's limit cycle, where the record starts, was not found at the diagnosis's \
         integrator tolerance rtol = {rtol:e}: {reason}"
    )]
    StartState {
        /// The integrator tolerance.
        rtol: f64,
        /// What went wrong.
        reason: String,
    },
    /// A model cannot be simulated on the record.
    #[error("simulation failed at t = {time} s: {reason}")]
    Simulation {
        /// Time of the failure (s).
        time: f64,
        /// What went wrong.
        reason: String,
    },
    /// The configured model's output misses the record by orders of magnitude before any fit:
    /// a parameter or a column in the wrong unit, which no refit repairs (and fitting it would
    /// run for long).
    #[error(
        "the configured model's output {output} misses the record by {nrmse:.3e} times the \
         record's spread (more than {limit:e}): check the parameter values and the units of the \
         measured column"
    )]
    ScaleMismatch {
        /// The output's name.
        output: String,
        /// RMS error of the configured simulation over the output's standard deviation.
        nrmse: f64,
        /// The largest accepted ratio.
        limit: f64,
    },
    /// The configured model's output moves against the record's, or has its shape at a scale
    /// off by more than a factor 10, before any fit: a flipped sign or a unit slip, which a
    /// refit would only hide behind absurd values (and would run for long).
    #[error(
        "the configured model does not describe the record, so nothing is fitted; check, one by \
         one: {}",
        reasons.join("; ")
    )]
    ModelMismatch {
        /// Each reason, with the output and the check that found it.
        reasons: Vec<String>,
    },
    /// The model has no equations to place candidate effects in: a Rust model of code alone
    /// (its `Rhythmic::equations` gives `None`).
    #[error(
        "the model has no equations in the model language, and the diagnosis adds each \
         candidate effect as a term to them: give them with Rhythmic::equations (a model file \
         read with htfid_lang::Model is its own), or diagnose the model's file"
    )]
    NoEquations,
    /// The model's equations, written by its `Rhythmic::equations`, do not read.
    #[error("the model's equations do not read: {reason}")]
    Equations {
        /// The model language's message.
        reason: String,
    },
    /// The model's equations are another system than the model: driven alike from their
    /// limit cycles, an output differs by more than
    /// [`EQUATIONS_TOLERANCE`](crate::EQUATIONS_TOLERANCE) of its spread.
    #[error(
        "the model's equations (Rhythmic::equations) are not the model: driven by the record's \
         input from their limit cycles, output {output} differs from the model's by {difference:.3e} \
         at t = {time} s, {:.1e} of its spread {spread:.3e} (at most {:.0e}); check the equations \
         against the model's code term by term",
        difference / spread,
        crate::EQUATIONS_TOLERANCE
    )]
    EquationsDisagree {
        /// The output's name in the equations.
        output: String,
        /// The largest difference, in the output's unit.
        difference: f64,
        /// The output's spread on the check (max - min).
        spread: f64,
        /// When the difference is largest, s.
        time: f64,
    },
    /// The fit of the configured model's free parameters failed.
    #[error("fitting the nominal model failed: {reason}")]
    NominalFit {
        /// What went wrong.
        reason: String,
    },
}
