//! Unit tests of `record::writer` (src/record/writer.rs), kept out of the library so that
//! `cargo test` does not compile the library a second time for them.

use agglo::record::writer::sorted_difference;

#[test]
fn difference_of_sorted_ids() {
    let gone: Vec<u64> = sorted_difference(&[1, 2, 3, 5, 8], &[2, 5, 6, 9]).collect();
    assert_eq!(gone, vec![1, 3, 8]);
    assert_eq!(sorted_difference(&[], &[1]).count(), 0);
    assert_eq!(sorted_difference(&[4], &[]).collect::<Vec<_>>(), vec![4]);
}
