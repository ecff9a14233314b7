//! Prints the home joint solution (flange down, cup centre 0.2 m above the table at y = 0.25 m).
use nalgebra::{Isometry3, Translation3};
fn main() {
    let seed = [-1.5, -1.6, -1.6, -1.5, 1.57, 0.0];
    for seed in [seed, [1.5, -1.6, 1.6, -1.5, -1.57, 0.0], [-1.5, -1.2, 1.6, -1.9, -1.57, 0.0]] {
        let t =
            Isometry3::from_parts(Translation3::new(0.05, 0.25, 0.20 + 0.05), tile_sim::expert::tool_down());
        let q = tile_sim::expert::ik_dls(&t, &seed);
        println!("{q:?}");
        if let Some(q) = q {
            let f = ur3_kin::fk_all(&ur3_kin::UR3, &q);
            for fr in f.iter() {
                println!("  {:.3?}", fr.translation.vector.as_slice());
            }
        }
    }
}
