//! `heml materials`: the registry, with parameters and energies; or one energy
//! given as text, checked and differentiated.

use clap::Args;
use heml::law::InvariantLaw;
use heml::law::LawKind;
use heml::RuntimeLaw;

/// Arguments of `heml materials`.
#[derive(Args, Debug)]
pub struct MaterialsArgs {
    /// An energy w(I1, I2, J) in the language of `#[heml::material]`, e.g.
    /// "mu/2*(I1-3) - mu*ln(J) + lambda/2*ln(J).powi(2)": checked, and its
    /// derivatives printed, instead of the registry's list.
    #[arg(long, value_name = "TEXT")]
    pub energy: Option<String>,
    /// Parameter NAME=VALUE of --energy (repeatable; every name the energy uses).
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Do not build the J0 inversion extension (for an energy finite for J <= 0).
    #[arg(long)]
    pub no_inversion_fix: bool,
    /// The law's volumetric energy U(J) of --energy, e.g. "kappa/2*(J-1).powi(2)"
    /// (J and the parameters; U(1) = U'(1) = 0 and U''(1) = the law's bulk modulus):
    /// checked, and its derivatives printed (a scene's `volumetric_energy`).
    #[arg(long, value_name = "TEXT", requires = "energy")]
    pub volumetric_energy: Option<String>,
}

/// Prints every registered law, or the checked --energy.
pub fn run(args: MaterialsArgs) -> heml::Result<()> {
    match &args.energy {
        Some(energy) => print_energy(energy, &args),
        None => {
            print_materials();
            Ok(())
        }
    }
}

/// The law of `energy`: its parameters, derivatives and rest state.
fn print_energy(energy: &str, args: &MaterialsArgs) -> heml::Result<()> {
    let params = super::info::parse_params(&args.params)?;
    let mut law = RuntimeLaw::with_inversion_fix(energy, &params, !args.no_inversion_fix)?;
    if let Some(u) = &args.volumetric_energy {
        law = law.with_volumetric_energy(u)?;
    }
    outln!("w = {energy}");
    let shown: Vec<String> = law
        .param_info()
        .iter()
        .zip(law.values())
        .map(|(p, v)| format!("{} = {v}", p.name))
        .collect();
    outln!(
        "parameters: {}",
        if shown.is_empty() {
            "none".into()
        } else {
            shown.join(", ")
        }
    );
    let (uses_i2, uses_j) = law.uses();
    let ops = law.op_count();
    outln!(
        "uses I2: {uses_i2}   uses J: {uses_j}   J0 inversion extension: {}   value+gradient: {} operations",
        law.extended(),
        ops.add + ops.mul + ops.div + ops.func
    );
    outln!();
    for (name, expr) in law.derivatives() {
        outln!("{name:<10} = {expr}");
    }
    if !law.volumetric_derivatives().is_empty() {
        // checked against the law along pure dilations as it was declared, above
        let k0 = InvariantLaw::volumetric(&law, 1.0).map_or(f64::NAN, |[_, _, u2]| u2);
        outln!();
        outln!("volumetric energy (U(1) = U'(1) = 0, U''(1) = K0 = {k0:e}):");
        for (name, expr) in law.volumetric_derivatives() {
            outln!("{name:<10} = {expr}");
        }
    }
    // at rest: P = (2 w1 + 4 w2 + wJ) I must vanish for a stress-free rest state (a
    // law that is not gets the library's warning as it is built, above)
    let rest = law.rest_state();
    outln!();
    outln!(
        "at rest (I1 = I2 = 3, J = 1): w = {:e}, stress factor 2w1 + 4w2 + wJ = {:e}",
        rest.energy,
        rest.stress
    );
    Ok(())
}

fn print_materials() {
    for e in heml::materials_list() {
        let kind = match e.kind {
            LawKind::Invariant => "w(I1, I2, J)",
            LawKind::Link => "link w(l, L)",
            LawKind::Stretch => "w(λ1, λ2, λ3, J)",
            LawKind::Fibre => "fibre w(I1, I2, J, I4, I5)",
        };
        outln!("{}  [{kind}]  {}", e.name, e.title());
        for p in e.params {
            outln!(
                "    {:<8} {}{}",
                p.name,
                p.doc,
                if p.signed { " (may be negative)" } else { "" }
            );
        }
        let tidy = |text: &str| text.split_whitespace().collect::<Vec<_>>().join(" ");
        outln!("    w = {}", tidy(e.energy));
        if let Some(u) = e.volumetric {
            outln!(
                "    U = {}  (declared volumetric energy, for volumetric = \"nodal\" or \"patch\")",
                tidy(u)
            );
        }
        outln!();
    }
}
