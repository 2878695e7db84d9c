//! Unit tests of `inverse::genes` (src/inverse/genes.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::inverse::genes::*;
use serde_json::json;

#[test]
fn sets_object_and_array_paths() {
    let mut v = json!({"cloud": {"v_rel": [1.0, 2.0, 3.0]}, "material": {"gamma": null}});
    set_path(&mut v, "cloud.v_rel.1", 5.5).unwrap();
    set_path(&mut v, "material.gamma", 7.0).unwrap();
    assert_eq!(get_path(&v, "cloud.v_rel.1"), Some(&json!(5.5)));
    assert_eq!(get_path(&v, "material.gamma"), Some(&json!(7.0)));
    assert!(set_path(&mut v, "cloud.v_rel.3", 1.0).is_err());
    assert!(set_path(&mut v, "cloud.nope", 1.0).is_err());
    assert!(set_path(&mut v, "cloud", 1.0).is_err());
}
