//! `heml materials`: the registry, with parameters and energies.

use heml::law::LawKind;

/// Prints every registered law.
pub fn run() -> heml::Result<()> {
    print_materials();
    Ok(())
}

fn print_materials() {
    for e in heml::materials_list() {
        let kind = match e.kind {
            LawKind::Invariant => "w(I1, I2, J)",
            LawKind::Link => "link w(l, L)",
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
        outln!(
            "    w = {}\n",
            e.energy.split_whitespace().collect::<Vec<_>>().join(" ")
        );
    }
}
