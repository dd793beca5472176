//! `citywalk`: the command line for everything — generate, preprocess, inspect, render, view,
//! bench and demo. Library code reports typed errors; this binary turns them into messages.

use clap::{Parser, Subcommand};

mod allocator;
mod bench;
mod cli_args;
mod demo;
mod error_message;
mod export;
mod generate;
mod input_args;
mod inspect;
mod path_arg;
mod preprocess;
mod render;
mod report_items;
mod scene_input;
mod texture_args;
mod tile_jobs;
mod view;

/// citywalk: an occlusion-aware urban walkthrough engine.
#[derive(Debug, Parser)]
#[command(name = "citywalk", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The main job: preprocess the bundled Chelsea extract and benchmark a walk and a flyover.
    Demo(demo::Args),
    /// Generate a procedural city as GeoJSON (buildings and streets).
    Generate(generate::Args),
    /// Preprocess inputs into a scene package (.cwk).
    Preprocess(preprocess::Args),
    /// Summarise and check a scene or package.
    Inspect(inspect::Args),
    /// Render frames of a scene to PNG, headless.
    Render(render::Args),
    /// Open a window to walk or fly through a scene.
    View(view::Args),
    /// The occlusion benchmark: scenes x camera paths x culling modes, checked by the oracle.
    Bench(bench::Args),
    /// Export a scene as a 3D Tiles 1.1 tileset (the cluster tree as HLOD) or one GLB.
    Export(export::Args),
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
                tracing_subscriber::EnvFilter::new("info,wgpu_core=warn,wgpu_hal=warn,naga=warn")
            }),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Generate(args) => generate::run(args),
        Command::Preprocess(args) => preprocess::run(args),
        Command::Inspect(args) => inspect::run(args),
        Command::Render(args) => render::run(args),
        Command::View(args) => view::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Export(args) => export::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // The message and its causes only: an error the user caused needs no backtrace,
            // even with RUST_BACKTRACE set (bugs panic, and panics keep theirs).
            eprintln!("error: {}", error_message::error_line(&e));
            std::process::ExitCode::FAILURE
        }
    }
}
