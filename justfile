# htfid task runner. `just ci` is what CI runs (via .ci/run).

default: test

# Format check, lints as errors, docs, and the whole test suite.
test: fmt-check clippy doc tests

# Alias kept for CI scripts.
ci: test

fmt-check:
    cargo fmt --all -- --check

clippy:
    cargo clippy --workspace --all-targets --locked -- -D warnings

doc:
    RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

tests:
    cargo test --workspace --locked

# The main job: the paper's experiment end to end.
run config="configs/paper.toml":
    cargo run --release --locked --bin htfid -- run {{config}}

# Benchmarks (release build); figures go to docs/performance.md.
bench:
    cargo bench -p htfid --bench pipeline
