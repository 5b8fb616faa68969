//! The `unz` command line. Only this file maps errors to exit codes.

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = unz::cli::Cli::parse();
    // A process that works on one run starts again with its heap in huge pages (first
    // thing: no thread, lock or file is taken yet).
    if unz::commands::works_on_one_run(&cli.command) {
        unz::memory::with_huge_pages();
        // Huge pages are zeroed whole on first touch: what is freed is kept for reuse.
        if unz::memory::heap_in_huge_pages() {
            unz::memory::keep_freed_memory();
        }
        // Said in the logs (stderr not a terminal), as the stages' phases are.
        if unz::memory::heap_in_huge_pages()
            && !std::io::IsTerminal::is_terminal(&std::io::stderr())
        {
            eprintln!("unz: the heap in transparent huge pages");
        }
    }
    match unz::commands::run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(2)
        }
    }
}
