//! Prints the report of the headline HTF design, and its JSON form with `--json`.
//!
//! `cargo run --release -p htfid-excite --example design_report [-- --json]`

use htfid_excite::{design_htf_multisine, Amplitude, DesignSpec, EvenOrder, PhaseRule};

fn main() -> Result<(), htfid_excite::ExciteError> {
    let design = design_htf_multisine(DesignSpec {
        period: 1.0,
        max_harmonic: 3,
        omega_lo: 1.0,
        omega_hi: 40.0,
        spacing: 0.45,
        amplitude: Amplitude::Peak(0.004),
        phases: PhaseRule::Schroeder,
        even_order: EvenOrder::SignReversal,
        settle: 10.0,
        start: 30.0,
        max_record: 600.0,
    })?;
    let report = design.report();
    if std::env::args().any(|a| a == "--json") {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("report serializes")
        );
    } else {
        print!("{report}");
    }
    Ok(())
}
