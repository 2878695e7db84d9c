//! The laws: pure numerics with no ECS types, unit-tested on their own. The engine and
//! the built-in systems call them; so can any extension or study.
//!
//! - [`hardness`]: the Arrhenius hardness and its overflow rule (docs/model.md §1);
//! - [`contact_time`]: when two ballistic spheres touch (§4);
//! - [`flight`]: closed-form flights in a field (g, linear drag) and the safeguarded
//!   contact and cell-crossing search along them (§4.7);
//! - [`impact`]: the pair's impact/heat fixed point, its solve and closed forms (§5, §14);
//! - [`grid`]: the periodic cell grid that finds near pairs, and the periodic images (§4, §9);
//! - [`cooling`]: the cooling law, its integrators and closed forms (§8);
//! - [`fragmentation`]: the pieces an absorbed energy makes and their surface energy (§7).

pub mod contact_time;
pub mod cooling;
pub mod flight;
pub mod fragmentation;
pub mod grid;
pub mod hardness;
pub mod impact;
