//! The laws: pure numerics with no ECS types, unit-tested on their own. The engine and
//! the built-in systems call them; so can any extension or study.

pub mod cooling;
