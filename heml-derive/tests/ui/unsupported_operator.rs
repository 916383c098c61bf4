/// `^` is not a power in Rust (nor here).
#[heml_derive::material(name = "caret")]
#[energy(mu * (I1 - 3.0) ^ 2.0)]
pub struct Caret {
    pub mu: f64,
}

fn main() {}
