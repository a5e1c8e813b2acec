//! Every `tutti` (and `tutti-bench`, `tutti-demo`) command shown in a shell block of README.md and docs/*.md names a real
//! subcommand with flags that exist: each is run with `--help` appended (which clap answers
//! only when everything before it parses). Every `python3 launch-scripts/…` command has its
//! arguments parsed by the script's own argparse parser and stops there (see [`PARSE_ONLY`]),
//! except the ROS 2 nodes' (`ros2_*.py`: they need rclpy). Synopsis lines (with `[...]` or `|`) and lines
//! that pipe or substitute are left out.

use tutti_test_support as common;

use std::path::Path;
use std::process::Command;

/// Runs a Python script (`python3 -c PARSE_ONLY SCRIPT ARGS…`) until its argparse parser has
/// parsed ARGS: a bad or unknown argument exits 2 with argparse's message, else it exits 0
/// without running the script any further.
const PARSE_ONLY: &str = "import argparse, runpy, sys\n\
parse = argparse.ArgumentParser.parse_args\n\
def parse_only(self, args=None, namespace=None):\n    parse(self, args, namespace)\n    sys.exit(0)\n\
argparse.ArgumentParser.parse_args = parse_only\n\
sys.argv = sys.argv[1:]\n\
runpy.run_path(sys.argv[0], run_name='__main__')\n";

/// The `tutti` and `python3 launch-scripts/…` commands in the shell blocks of `text`, with
/// their line: (line, as shown, program, arguments).
fn commands(text: &str) -> Vec<(usize, String, &'static str, Vec<String>)> {
    let mut out = Vec::new();
    let mut shell = false;
    // Lines continued with a trailing backslash, joined (and numbered by their first line).
    let mut joined: Vec<(usize, String)> = Vec::new();
    let mut continued = false;
    for (i, line) in text.lines().enumerate() {
        let piece = line.trim_end().strip_suffix('\\');
        match (continued, joined.last_mut()) {
            (true, Some((_, last))) => {
                last.push(' ');
                last.push_str(piece.unwrap_or(line).trim());
            }
            _ => joined.push((i, piece.unwrap_or(line).to_string())),
        }
        continued = piece.is_some();
    }
    for (i, line) in joined {
        let line = line.as_str();
        let trimmed = line.trim_start();
        if let Some(info) = trimmed.strip_prefix("```") {
            shell = !shell && matches!(info.trim(), "sh" | "bash" | "shell" | "console");
            continue;
        }
        if !shell {
            continue;
        }
        let cmd = line.split(" #").next().unwrap_or("").trim().trim_start_matches("$ ");
        // Two commands side by side (one per machine), or a synopsis: not one command line.
        if cmd.matches("tutti ").count() > 1
            || cmd.contains('[')
            || cmd.contains('|')
            || cmd.contains("$(")
            || cmd.contains('>')
            || cmd.contains('&')
        {
            continue;
        }
        let mut words = cmd.split_whitespace().skip_while(|w| w.contains('=') && !w.starts_with('-') || *w == "sudo");
        let program = match words.next() {
            Some("tutti") => env!("CARGO_BIN_EXE_tutti"),
            Some("tutti-bench") => "tutti-bench",
            Some("tutti-demo") => "tutti-demo",
            Some("python3") if cmd.contains("launch-scripts/") && !cmd.contains("ros2_") => "python3",
            _ => continue,
        };
        let args: Vec<String> = words.map(|w| w.trim_matches(|c| c == '\'' || c == '"').to_string()).collect();
        out.push((i + 1, cmd.to_string(), program, args));
    }
    out
}

#[test]
fn every_documented_command_parses() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = vec![root.join("README.md")];
    let mut docs: Vec<_> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    let mut checked = 0;
    let mut bad = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        for (line, shown, program, args) in commands(&text) {
            // The benchmarks' and the demo's executables, built beside tutti when first shown.
            let mut c = match program {
                "tutti-bench" => Command::new(common::workspace_bin("tutti-bench", "tutti-bench")),
                "tutti-demo" => Command::new(common::workspace_bin("tutti-uav-demo", "tutti-demo")),
                _ => Command::new(program),
            };
            if program == "python3" {
                c.arg("-c").arg(PARSE_ONLY).args(&args).current_dir(root);
            } else {
                c.args(&args).arg("--help").current_dir(root);
            }
            let (status, _, err) = common::run_with_timeout(c, std::time::Duration::from_secs(60));
            checked += 1;
            if !status.success() {
                let first = err.lines().next().unwrap_or("").to_string();
                bad.push(format!("{}:{line}: {shown}\n    {first}", file.strip_prefix(root).unwrap().display()));
            }
        }
    }
    assert!(checked > 20, "only {checked} commands found: is the extraction broken?");
    assert!(bad.is_empty(), "documented commands that do not parse:\n{}", bad.join("\n"));
}
