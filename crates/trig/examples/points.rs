//! Prints `x sin(x) cos(x)` for 40 000 seeded random arguments in each of `[-1, 1]`,
//! `[-2000, 2000]` and `[-1e6, 1e6]`, every number with the digits that read back to the same
//! double: the input of `tests/oracle/trig_exact.py`, which compares them with the exact values.
//!
//! `cargo run --release -p htfid-trig --example points | python3 tests/oracle/trig_exact.py`

use std::io::Write;

fn main() -> std::io::Result<()> {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    for range in [1.0, 2000.0, 1e6] {
        for _ in 0..40_000 {
            let x = (2.0 * uniform() - 1.0) * range;
            writeln!(
                out,
                "{x:e} {:e} {:e}",
                htfid_trig::sin(x),
                htfid_trig::cos(x)
            )?;
        }
    }
    out.flush()
}
