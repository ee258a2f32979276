fn main() {
    let p = host_sim::plant::PlantParams::default();
    for (n, r) in p.fastest_rates_per_s() { println!("{n:35} {r:10.0}  r*h4 {:.3}  r*h2 {:.3}", r * 12.5e-6, r * 25e-6); }
}
