//! duocan's test tiers against real things (not published). The tests live in `tests/`, each
//! behind the feature of its tier; `.ci/tier-vcan.sh`, `.ci/tier-python.sh` and
//! `.ci/tier-tshark.sh` install what a tier needs and run it. Without its feature a tier's test
//! is not built at all, so `cargo test --workspace` never reports a tier as passed.
