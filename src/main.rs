//! The `terrastitch` command: `serve`, `render`, `seed`, `export`, `import` and `update`
//! (see [`terrastitch::cli`]).

/// The system allocator, counting what a render allocates against its memory budget
/// (`server.render_memory_mib`).
#[global_allocator]
static ALLOCATOR: terrastitch::budget::Counting = terrastitch::budget::Counting;

fn main() -> anyhow::Result<()> {
    terrastitch::cli::main()
}
