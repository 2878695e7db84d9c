//! Unit tests of `live` (src/live/mod.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::live::*;

#[test]
fn addresses_parse_or_are_refused_by_name() {
    assert_eq!(
        parse_addr("127.0.0.1:8765").unwrap(),
        "127.0.0.1:8765".parse().unwrap()
    );
    assert_eq!(parse_addr("[::1]:9").unwrap().port(), 9);
    for bad in [
        "nonsense",
        "127.0.0.1",
        "scenarios/quick_demo.json",
        "1.2.3.4:99999",
    ] {
        let e = parse_addr(bad).unwrap_err().to_string();
        assert!(e.contains(bad) && e.contains("not an address"), "{e}");
    }
}

#[test]
fn options_out_of_range_are_refused() {
    let ok = LiveOptions {
        addr: parse_addr(DEFAULT_ADDR).unwrap(),
        wait: false,
        rate_hz: 10.0,
        max_bodies: 10_000,
        linger_seconds: DEFAULT_LINGER_SECONDS,
        pace: None,
    };
    assert!(check_options(&ok).is_ok());
    for rate in [0.0, -1.0, f64::NAN, 1e4] {
        let e = check_options(&LiveOptions {
            rate_hz: rate,
            ..ok.clone()
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("--live-rate"), "{e}");
    }
    for pace in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        let e = check_options(&LiveOptions {
            pace: Some(pace),
            ..ok.clone()
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("--live-pace"), "{e}");
    }
    for linger in [-1.0, f64::NAN, f64::INFINITY, 1e6] {
        let e = check_options(&LiveOptions {
            linger_seconds: linger,
            ..ok.clone()
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("--live-linger"), "{e}");
    }
    let e = check_options(&LiveOptions {
        max_bodies: 0,
        ..ok
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("--live-bodies"), "{e}");
}
