//! Unit tests of `study::readings` (src/study/readings/mod.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::scenario::Scenario;
use agglo::study::readings::*;

#[test]
fn combinations_take_none_or_one_of_each_group() {
    let base = Scenario::from_json(include_str!("../../../scenarios/paper2004_best.json")).unwrap();
    let all = catalogue(&base);
    let groups = vec![
        vec![
            "solver_plain".to_string(),
            "solver_plain_cap_parity".to_string(),
        ],
        vec!["v_rel_yz_10".to_string()],
    ];
    let combos = combinations(&all, &groups);
    let keys: Vec<&str> = combos.iter().map(|r| r.key.as_str()).collect();
    assert_eq!(
        keys,
        [
            BASELINE,
            "v_rel_yz_10",
            "solver_plain",
            "solver_plain+v_rel_yz_10",
            "solver_plain_cap_parity",
            "solver_plain_cap_parity+v_rel_yz_10",
        ]
    );
    // The merged patch carries both readings.
    let s = scenario_for(&base, &combos[5], base.seed, None).unwrap();
    assert_eq!(s.impact.max_iterations, 101);
    assert_eq!(s.cloud.v_rel.unwrap()[1], 10.0);
}

#[test]
fn the_catalogue_changes_every_scene_it_is_offered_for() {
    for text in [
        include_str!("../../../scenarios/paper2004_best.json"),
        include_str!("../../../scenarios/paper2002_best.json"),
    ] {
        let base = Scenario::from_json(text).unwrap();
        let readings = catalogue(&base);
        assert_eq!(readings[0].key, BASELINE);
        let baseline = scenario_for(&base, &readings[0], base.seed, None).unwrap();
        assert_eq!(baseline, base, "the baseline is the scenario itself");
        for r in &readings[1..] {
            let s = scenario_for(&base, r, base.seed, None)
                .unwrap_or_else(|e| panic!("{}: {e}", r.key));
            assert_ne!(s, base, "{} changes nothing", r.key);
            assert!(!r.what.contains(',') && !r.key.contains(' '), "{}", r.key);
        }
    }
}
