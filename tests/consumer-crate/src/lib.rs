//! Nothing but tests: see `tests/core_api.rs`. The crate exists to depend on lensbake with
//! `default-features = false`, as a user's crate would.
