# htfid task runner. `just ci` is what CI runs (via .ci/run).

default: test

# Format check, lints as errors, docs, the whole test suite, the diagnosis's wide hidden-effect
# sweeps (two protocols) and the full fuzz suite.
test: fmt-check clippy doc tests model-sweep model-sweep-configured fuzz

# Alias kept for CI scripts.
ci: test

fmt-check:
    cargo fmt --all -- --check

clippy:
    cargo clippy --workspace --all-targets --locked -- -D warnings

doc:
    RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

# The release profile, as the README's commands: the tests reuse the build of `htfid run`.
tests:
    cargo test --release --workspace --locked

# The diagnosis on 77 core records of the independent truth generator (htfid-truth): single
# and compound effects, sensor-side effects, effects outside the library, clean data; the
# records side by side, with the floors measured on them (about 20 minutes on 2 cores).
model-sweep:
    cargo test --release --locked -p htfid-diagnose --test model_language_sweep -- --ignored --nocapture

# The same records with nothing refitted: an error of m, k or c is the candidate
# parameter_error (about 13 minutes on 2 cores).
model-sweep-configured:
    HTFID_MODEL_SWEEP_PROTOCOL=configured cargo test --release --locked -p htfid-diagnose --test model_language_sweep -- --ignored --nocapture

# The fuzz and fault suite over more seeds than `cargo test` runs (880 cases, about 2 minutes).
fuzz:
    cargo test --release --locked -p htfid --test fuzz -- --ignored

# The main job: the paper's experiment end to end.
run config="configs/paper.toml":
    cargo run --release --locked --bin htfid -- run {{config}}

# Benchmarks (release build); figures go to docs/performance.md.
bench:
    cargo bench -p htfid --bench pipeline
