//! Unit tests of `cli::live` (src/cli/live.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::cli::live::recorded_command_line;

fn line(args: &str) -> String {
    recorded_command_line(args.split(' ').map(String::from))
}

#[test]
fn live_flags_are_left_out_of_the_recorded_command_line() {
    let want = "agglo run s.json --out run.mcap -q";
    for with in [
        "agglo run s.json --live --out run.mcap -q",
        "agglo run s.json --live 127.0.0.1:9 --out run.mcap -q",
        "agglo run s.json --live=127.0.0.1:9 --live-wait --out run.mcap -q",
        "agglo run s.json --out run.mcap --live-rate 5 --live-bodies=10 -q --live",
    ] {
        assert_eq!(line(with), want, "{with}");
    }
    assert_eq!(line(want), want);
}
