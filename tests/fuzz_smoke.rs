//! The fuzz harness's smoke run: a few hundred seeded mutations of valid inputs per format (fixed
//! seed, seconds in all), with no panic allowed. The long run is `examples/fuzz.rs` (README,
//! development section).

#[path = "fuzz/mod.rs"]
mod fuzz;

use fuzz::{run_range, Format};

const SEED: u64 = 17;

fn smoke(format: Format, cases: u64) {
    let tally = run_range(SEED, format, 0, cases, |_| {});
    assert_eq!(tally.cases, cases);
    assert!(
        tally.panics.is_empty(),
        "{} panics in {} {} cases, first: case {} ({})",
        tally.panics.len(),
        cases,
        format.name(),
        tally.panics[0].0,
        tally.panics[0].1
    );
    // The mutations must exercise both sides of the loaders: some cases get past every check and
    // load, and some are refused (with one-line errors of the expected kinds, which the harness
    // checks). A mutator that only ever broke its input, or never did, would test nothing.
    let rejected: u64 = tally.rejected.values().sum();
    assert!(
        tally.accepted > 0,
        "{}: no mutated case was accepted",
        format.name()
    );
    assert!(
        rejected > 0,
        "{}: no mutated case was refused",
        format.name()
    );
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_obj() {
    smoke(Format::Obj, 400);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_ply() {
    smoke(Format::Ply, 300);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_pgm() {
    smoke(Format::Pgm, 300);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_map_yaml() {
    smoke(Format::MapYaml, 300);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_houseexpo() {
    smoke(Format::HouseExpo, 300);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_config_toml() {
    smoke(Format::ConfigToml, 400);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_set() {
    smoke(Format::Set, 400);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_mcap() {
    smoke(Format::Mcap, 300);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_glb() {
    smoke(Format::Glb, 300);
}

#[test]
#[ignore = "heavy tier: cargo test -- --ignored"]
fn fuzz_smoke_gltf() {
    smoke(Format::Gltf, 300);
}

/// The mutator is deterministic: a case is reproduced from its index alone.
#[test]
fn fuzz_cases_are_reproducible() {
    for format in Format::ALL {
        let seeds = fuzz::seeds(format);
        for i in [0, 7, 12345] {
            assert_eq!(
                fuzz::case_input(SEED, format, i, &seeds),
                fuzz::case_input(SEED, format, i, &seeds)
            );
        }
    }
    let seeds = vec![b"0123456789abcdef".to_vec()];
    assert_eq!(
        fuzz::case_input(1, Format::Mcap, 3, &seeds),
        fuzz::case_input(1, Format::Mcap, 3, &seeds)
    );
    assert_ne!(
        fuzz::case_input(1, Format::Mcap, 3, &seeds),
        fuzz::case_input(1, Format::Mcap, 4, &seeds)
    );
}
