//! `mta status`: which mtanet processes and topics exist in a namespace, and whether a crashed
//! process left a dead node behind (and cleans it with `--cleanup`).

use mtanet_ipc::cli::CommonArgs;
use mtanet_ipc::node::{census, create_node, services};

#[derive(Debug, clap::Args)]
pub struct StatusArgs {
    #[command(flatten)]
    common: CommonArgs,
    /// Remove the resources of dead nodes (processes that crashed or were killed).
    #[arg(long)]
    cleanup: bool,
}

pub fn run(args: StatusArgs) -> anyhow::Result<()> {
    let (_, ipc) = args.common.load()?;
    if args.cleanup {
        // Creating a node cleans dead nodes of the namespace (see mtanet_ipc::node).
        drop(create_node(&ipc, "mta-status")?);
    }
    let nodes = census(&ipc)?;
    println!("namespace {}", ipc.namespace);
    println!(
        "  nodes alive: {}",
        if nodes.alive.is_empty() {
            "-".into()
        } else {
            nodes.alive.join(", ")
        }
    );
    if !nodes.dead.is_empty() {
        println!(
            "  nodes DEAD:  {} (run `mta status --cleanup`)",
            nodes.dead.join(", ")
        );
    }
    let svcs = services(&ipc)?;
    if svcs.is_empty() {
        println!("  services:    -");
    }
    for s in svcs {
        println!(
            "  service {:<22} {:<17} nodes {}",
            s.name, s.pattern, s.nodes
        );
    }
    Ok(())
}
