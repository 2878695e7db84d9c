//! The readings offered for a scene: each a patch to the scenario, with what it
//! changes and where the papers print it.

use super::*;

/// The runnable readings that differ from `base` (docs/model.md, "Readings"). A reading
/// that would leave `base` unchanged (e.g. the P02 duration law on a P02 scene) is
/// replaced by its counterpart or left out.
pub fn catalogue(base: &Scenario) -> Vec<Reading> {
    let i = &base.impact;
    let mut out = vec![Reading::new(
        BASELINE,
        "the scenario as given (engine readings)",
        "docs/model.md",
        json!({}),
    )];
    for (rule, what) in [
        ("harmonic", "harmonic mean of H_i and H_j"),
        ("arithmetic", "arithmetic mean of H_i and H_j"),
        ("max", "larger of H_i and H_j (both surfaces must yield)"),
    ] {
        out.push(Reading::new(
            &format!("pair_hardness_{rule}"),
            &format!("G(e) against the {what}"),
            "P02 (20) writes H without saying whose; P04 uses min",
            json!({ "impact": { "pair_hardness": rule } }),
        ));
    }
    out.push(Reading::new(
        "friction_uncapped",
        "the full Coulomb impulse (may reverse sliding)",
        "P04 (4.17) and P02 (7) as printed",
        json!({ "impact": { "friction_cap": "none" } }),
    ));
    out.push(Reading::new(
        "work_heat_twice",
        "the dissipation heats the pair twice: dK plus the deformation work dW",
        "P04 (6.8) and (6.10)",
        json!({ "impact": { "work_heat": "twice" } }),
    ));
    out.push(Reading::new(
        "bond_any_iterate",
        "bond as soon as an iterate from e0 = 0 presses at 2H",
        "P02 (20) in-loop accretion test",
        json!({ "impact": { "bond_test": "any_iterate" } }),
    ));
    out.push(Reading::new(
        "separation_velocities",
        "overlaps removed along each body's own velocity",
        "P02 (8)",
        json!({ "impact": { "separation": "velocities" } }),
    ));
    let (other, law) = match i.duration {
        DurationLaw::P04 => ("duration_p02", "p02"),
        DurationLaw::P02 => ("duration_p04", "p04"),
    };
    out.push(Reading::new(
        other,
        &format!("the other paper's impact-duration law ({law})"),
        "P04 (4.10) against P02 (12)",
        json!({ "impact": { "duration": law } }),
    ));
    let (key, what) = if i.friction_scales_with_adhesion {
        ("friction_constant", "mu = mu0 (P04)")
    } else {
        ("friction_scales_with_adhesion", "mu = mu0 (1 - e) (P02)")
    };
    out.push(Reading::new(
        key,
        what,
        "P04 (4.17) against P02 after (7)",
        json!({ "impact": { "friction_scales_with_adhesion": !i.friction_scales_with_adhesion } }),
    ));
    if i.solver != SolverKind::Plain {
        out.push(Reading::new(
            "solver_plain",
            "the papers' plain iteration alone (last iterate if unconverged)",
            "P04 §6(b); P02 (20)",
            json!({ "impact": { "solver": "plain" } }),
        ));
        // The papers give no iteration cap; where the iteration 2-cycles (a0 = 0,
        // docs/model.md §5.2) its parity decides whether the last iterate is 0 (bond).
        let cap = i.max_iterations + 1;
        out.push(Reading::new(
            "solver_plain_cap_parity",
            &format!(
                "the plain iteration capped at {cap} instead of {} iterations (the other parity)",
                i.max_iterations
            ),
            "neither paper gives a cap",
            json!({ "impact": { "solver": "plain", "max_iterations": cap } }),
        ));
    }
    out.push(Reading::new(
        "solver_closed_form",
        "the closed form's root as the answer (pre-impact hardness; no iteration)",
        "P04 (4.13)-(4.14) corrected (docs/model.md §14)",
        json!({ "impact": { "solver": "closed_form" } }),
    ));
    if i.duration == DurationLaw::P04 {
        out.push(Reading::new(
            "solver_closed_form_printed",
            "P04 (4.14) as printed (spurious lambda in c1) as the answer",
            "P04 (4.14)",
            json!({ "impact": { "solver": "closed_form_printed" } }),
        ));
    }
    if base.physics.contact_rule != ContactRule::NearestNeighbour {
        out.push(Reading::new(
            "contact_nearest_neighbour",
            "a pair meets only if each is the other's nearest neighbour (stepped core)",
            "P04 (6.14) staggering rule",
            json!({ "physics": { "contact_rule": "nearest_neighbour" } }),
        ));
    }
    if base.physics.impacts_per_step == ImpactsPerStep::OnePerBody {
        out.push(Reading::new(
            "every_contact",
            "every contact found in a step is resolved instead of one per body (stepped core)",
            "P04 §6(b), P02 (20): several contacts of one particle not addressed",
            json!({ "physics": { "impacts_per_step": "every_contact" } }),
        ));
    }
    let cools = base.material.epsilon > 0.0 || base.material.hc > 0.0;
    if cools && base.physics.cooling != CoolingMethod::Explicit {
        out.push(Reading::new(
            "cooling_explicit",
            "forward Euler cooling at the scene's steps (stepped core)",
            "P04 (6.21); P02 (19)",
            json!({ "physics": { "cooling": "explicit" } }),
        ));
    }
    if cools && base.physics.cooling != CoolingMethod::ExplicitClamped {
        out.push(Reading::new(
            "cooling_explicit_clamped",
            "forward Euler cooling stopped at the equilibrium instead of crossing it (stepped core)",
            "P04 (6.21); P02 (19) without the blow-up",
            json!({ "physics": { "cooling": "explicit_clamped" } }),
        ));
    }
    if cools && i.duration == DurationLaw::P02 && base.physics.cooling != CoolingMethod::Off {
        // P02 (18)-(19) as printed cool per unit volume: about b/3 (~1e-6 here) times the
        // engine's per-area rate, i.e. practically not at all (docs/model.md §8).
        out.push(Reading::new(
            "cooling_p02_as_printed",
            "no cooling: P02 (18)-(19) per unit volume are ~b/3 times the per-area rate",
            "P02 (18)-(19)",
            json!({ "physics": { "cooling": "off" } }),
        ));
    }
    // Every reading the paper of the scene's duration law prints, taken together.
    let printed: &[&str] = match i.duration {
        DurationLaw::P04 => &[
            "friction_uncapped",
            "solver_plain",
            "contact_nearest_neighbour",
        ],
        DurationLaw::P02 => &[
            "friction_uncapped",
            "bond_any_iterate",
            "separation_velocities",
            "solver_plain",
            "contact_nearest_neighbour",
            "cooling_p02_as_printed",
        ],
    };
    let mut patch = json!({});
    let mut taken = Vec::new();
    for r in out.iter().filter(|r| printed.contains(&r.key.as_str())) {
        merge(&mut patch, &r.patch);
        taken.push(r.key.clone());
    }
    if taken.len() > 1 {
        let paper = match i.duration {
            DurationLaw::P04 => "P04",
            DurationLaw::P02 => "P02",
        };
        out.push(Reading::new(
            "papers_as_printed",
            &format!("all of: {}", taken.join(" + ")),
            &format!("{paper} as printed where it is explicit"),
            patch,
        ));
    }
    if i.duration == DurationLaw::P04 {
        // P04's own experiment: a0, af, β unstated (docs/model.md §13) and two printed
        // statements of the y/z velocity amplitudes; μ's table factor printed as 10⁻².
        if i.a0 == 0.0 {
            out.push(Reading::new(
                "a0_p02",
                "a0 = 0.01 (P02's value) instead of P04's logical choice a0 = 0",
                "P04 §8 does not give a0",
                json!({ "impact": { "a0": 0.01 } }),
            ));
        }
        let v_rel = base.cloud.v_rel.unwrap_or_default();
        let vx = v_rel[0];
        if vx > 0.0 && v_rel[1] == 0.1 * vx && v_rel[2] == 0.1 * vx {
            out.push(Reading::new(
                "v_rel_yz_10",
                "y and z amplitudes 10 m/s instead of 0.1 v0",
                "P04 §7 first statement (after (7.4))",
                json!({ "cloud": { "v_rel": [vx, 10.0, 10.0] } }),
            ));
        }
        if base.material.mu0 > 0.0 && base.material.mu0 < 0.01 {
            out.push(Reading::new(
                "mu_as_printed",
                "mu0 x 1e4: Table 2's factor 10^-2 taken as printed (outside P04's own range)",
                "P04 Table 2",
                json!({ "material": { "mu0": base.material.mu0 * 1e4 } }),
            ));
        }
    }
    out
}
