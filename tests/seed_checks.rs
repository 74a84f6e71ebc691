//! The acceptance values of shared/reference/seed-checks.md, through `armctl fk`, `jacobian` and
//! `ik` on the `planar:N` preset. The values are quoted to 8 decimals there, so they hold to 1e-8.
// The expected values are the document's decimals, not library constants.
#![allow(clippy::approx_constant)]

use workspace_tests::{armctl_json, numbers};

const TOL: f64 = 1e-8;

fn chain(q: &str, n: usize) -> Vec<f64> {
    let v = armctl_json(&["fk", "--arm", &format!("planar:{n}"), "--q", q]);
    numbers(&v["position"])
}

fn dchain(q: &str, n: usize) -> Vec<Vec<f64>> {
    let v = armctl_json(&["jacobian", "--arm", &format!("planar:{n}"), "--q", q]);
    v["jacobian"].as_array().unwrap().iter().map(numbers).collect()
}

fn close(actual: &[f64], expected: &[f64]) {
    assert_eq!(actual.len(), expected.len(), "{actual:?} vs {expected:?}");
    for (a, e) in actual.iter().zip(expected) {
        assert!((a - e).abs() <= TOL, "{actual:?} vs {expected:?}");
    }
}

#[test]
fn chain_positions() {
    let pi = std::f64::consts::PI;
    close(&chain("", 0), &[0.0, 0.0, 0.0]);
    close(&chain("0", 1), &[1.0, 0.0, 0.0]);
    close(&chain(&format!("{}", pi / 4.0), 1), &[0.70710678, 0.70710678, 0.0]);
    close(&chain("0.1,0.2,0.3,0.4", 4), &[3.31597858, 1.80146708, 0.0]);
    close(&chain(&format!("{pi},{pi},{pi},{pi}"), 4), &[0.0, 0.0, 0.0]);
}

#[test]
fn chain_jacobians() {
    let pi = std::f64::consts::PI;
    let planar_rows = |j: Vec<Vec<f64>>| (j[0].clone(), j[1].clone());
    let (x, y) = planar_rows(dchain("0", 1));
    close(&x, &[0.0]);
    close(&y, &[1.0]);
    let (x, y) = planar_rows(dchain(&format!("{}", pi / 4.0), 1));
    close(&x, &[-0.70710678]);
    close(&y, &[0.70710678]);
    let (x, y) = planar_rows(dchain("0,0,0,0", 4));
    close(&x, &[0.0; 4]);
    close(&y, &[4.0, 3.0, 2.0, 1.0]);
    let (x, y) = planar_rows(dchain("0.1,0.2,0.3", 3));
    close(&x, &[-0.9599961, -0.86016268, -0.56464247]);
    close(&y, &[2.77567627, 1.7806721, 0.82533561]);
}

/// Newton with the pseudoinverse, 8 iterations, no restarts.
fn newton(n: usize, seed: &str, target: &str) -> Vec<f64> {
    let v = armctl_json(&[
        "ik",
        "--arm",
        &format!("planar:{n}"),
        "--solver",
        "newton",
        "--seed",
        seed,
        "--target",
        target,
        "--max-iterations",
        "8",
        "--position-tolerance",
        "1e-9",
    ]);
    assert_eq!(v["status"], "converged", "{v}");
    assert!(v["iterations"].as_u64().unwrap() <= 8, "{v}");
    let q = numbers(&v["q"]);
    chain(&q.iter().map(f64::to_string).collect::<Vec<_>>().join(","), n)
}

#[test]
fn pseudoinverse_newton_reaches_in_8_iterations() {
    close(&newton(1, "0", "0,1,0"), &[0.0, 1.0, 0.0]);
    close(&newton(2, "0,0", "0.5,0.5,0"), &[0.5, 0.5, 0.0]);
}

/// 30 links: the default solver stays stable when the target jumps far between calls, each call
/// seeded with the previous answer.
#[test]
fn thirty_links_survive_far_jumps() {
    let targets = ["25,0,0", "-20,5,0", "3,-24,0", "0,0.5,0", "-1,-29,0", "29.5,0.1,0", "10,10,0"];
    let mut seed = vec!["0".to_string(); 30].join(",");
    for t in targets {
        let v = armctl_json(&["ik", "--arm", "planar:30", "--target", t, "--seed", &seed]);
        assert_eq!(v["status"], "converged", "target {t}: {v}");
        let q = numbers(&v["q"]);
        assert!(q.iter().all(|x| x.is_finite() && x.abs() <= std::f64::consts::PI));
        seed = q.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
    }
}
