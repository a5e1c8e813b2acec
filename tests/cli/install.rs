//! `launch-scripts/install.sh` into a temporary prefix, then clients built the ways real
//! projects build them, each run against a live `tutti host`: a C program with pkg-config,
//! one with CMake's `find_package(tutti)`, one the way the product's clients look for the
//! product (`RTAPI.h` and a library named `OpalOrchestra`), and the Python module installed
//! with pip into a fresh venv.

use tutti_test_support as common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const LIMIT: Duration = Duration::from_secs(300);

/// `tutti host` in its own namespace, stopped (SIGINT: it removes its segments) when dropped,
/// and what it may have left removed after it.
pub(crate) struct HostGuard {
    _host: common::Proc,
    _segments: common::RemoveSegments,
}

pub(crate) fn run(cmd: Command, what: &str) -> String {
    let (status, out, err) = common::run_with_timeout(cmd, LIMIT);
    assert!(status.success(), "{what} failed ({status}):\n{out}\n{err}");
    out
}

/// Runs the uav_reader program `exe` for 20 steps against the host: it reads Z = 1.5.
fn reads_from_the_host(exe: &Path, ns: &str, what: &str) {
    reads_from_the_host_with(Command::new(exe), ns, what)
}

/// As [`reads_from_the_host`], for the program `c` runs (with its own environment).
pub(crate) fn reads_from_the_host_with(mut c: Command, ns: &str, what: &str) {
    c.env("TUTTI_NAMESPACE", ns).arg(common::repo_root().join("ddf/multiuav.ddf")).args([
        "multiuav_uav2",
        "Z",
        "Elevation",
        "20",
        "2",
    ]);
    let out = run(c, what);
    assert_eq!(out.lines().filter(|l| l.contains("Z=1.5")).count(), 20, "{what}: {out}");
}

#[test]
fn an_installed_rtapi_builds_c_programs_with_pkg_config_and_cmake_and_a_pip_installed_python_module() {
    let (Some(_), Some(_), Some(_)) = (
        common::require_tool("pkg-config", "pkgconf"),
        common::require_tool("cmake", "cmake"),
        common::require_tool("gcc", "gcc"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("prefix");
    install_into(&prefix);

    let ns = tutti_test_support::namespace("install");
    let _host = start_host(&ns);
    the_installed_libraries_are_stripped(&prefix);
    let product = a_client_builds_in_the_products_layout(dir.path(), &prefix);

    let pc_path = prefix.join("lib/pkgconfig");
    let reader = common::repo_root().join("examples/c/uav_reader.c");
    a_pkg_config_build_reads_from_the_host(dir.path(), &prefix, &pc_path, &reader, &ns);
    let mut opal = Command::new(dir.path().join("reader-opal"));
    opal.env("LD_LIBRARY_PATH", &product);
    reads_from_the_host_with(opal, &ns, "the client in the product's layout");
    cmake_builds_read_from_the_host(dir.path(), &prefix, &reader, &ns);
    a_pip_installed_module_reads_from_the_host(dir.path(), &prefix, &pc_path, &ns);
}

/// `launch-scripts/install.sh --no-cli` into `prefix` installs the header, the libraries and
/// the pkg-config file.
fn install_into(prefix: &Path) {
    // Built here when the test runs before the workspace was built (cargo test alone).
    let build_dir: PathBuf = common::rtapi_lib_dir();
    let mut install = Command::new("bash");
    install
        .arg(common::repo_root().join("launch-scripts/install.sh"))
        .arg("--prefix")
        .arg(prefix)
        .arg("--build-dir")
        .arg(&build_dir)
        .arg("--no-cli");
    run(install, "install.sh");
    for f in
        ["include/RTAPI.h", "lib/librtapi.so.0", "lib/librtapi.a", "lib/libOpalOrchestra.so", "lib/pkgconfig/rtapi.pc"]
    {
        assert!(prefix.join(f).exists(), "{f} not installed");
    }
}

/// `tutti host` of ddf/multiuav.ddf in namespace `ns`, with multiuav_uav2/Z = 1.5.
fn start_host(ns: &str) -> HostGuard {
    start_host_with(common::tutti_command(), ns)
}

/// As [`start_host`], with the `tutti` that `host` runs (an installed one).
pub(crate) fn start_host_with(mut host: Command, ns: &str) -> HostGuard {
    let ddf = common::repo_root().join("ddf/multiuav.ddf");
    host.arg("host").arg(ddf).args(["--step", "2ms", "-q", "--set", "multiuav_uav2/Z=1.5"]).env("TUTTI_NAMESPACE", ns);
    let opts =
        common::Spawn { watchdog: Duration::from_secs(1800), grace: Duration::from_secs(5), ..Default::default() };
    HostGuard {
        _host: common::Proc::spawn_with("tutti host", host, opts),
        _segments: common::RemoveSegments(ns.to_string()),
    }
}

/// Stripped: no debug information in what is installed.
fn the_installed_libraries_are_stripped(prefix: &Path) {
    for f in ["lib/librtapi.so.0", "lib/libOpalOrchestra.so", "lib/librtapi.a"] {
        let mut readelf = Command::new("readelf");
        readelf.arg("-S").arg(prefix.join(f));
        let sections = run(readelf, &format!("readelf -S {f}"));
        assert!(!sections.contains(".debug_info"), "{f} carries debug information");
    }
}

/// The product's layout: a directory holding only libOpalOrchestra.so (and RTAPI.h), the
/// client (`dir`/reader-opal) linked against it, needing nothing else; returns the directory.
fn a_client_builds_in_the_products_layout(dir: &Path, prefix: &Path) -> PathBuf {
    let product = dir.join("opal");
    std::fs::create_dir_all(&product).unwrap();
    std::fs::copy(prefix.join("lib/libOpalOrchestra.so"), product.join("libOpalOrchestra.so")).unwrap();
    std::fs::copy(prefix.join("include/RTAPI.h"), product.join("RTAPI.h")).unwrap();
    let exe = dir.join("reader-opal");
    let mut gcc = Command::new("gcc");
    gcc.args(["-std=c99", "-Wall", "-Wextra", "-Werror"])
        .arg("-I")
        .arg(&product)
        .arg(common::repo_root().join("examples/c/uav_reader.c"))
        .arg("-L")
        .arg(&product)
        .arg("-lOpalOrchestra")
        .arg("-o")
        .arg(&exe);
    run(gcc, "gcc against libOpalOrchestra.so alone");
    let mut readelf = Command::new("readelf");
    readelf.arg("-d").arg(&exe);
    let dynamic = run(readelf, "readelf -d");
    assert!(dynamic.contains("[libOpalOrchestra.so]"), "the client does not name libOpalOrchestra.so:\n{dynamic}");
    assert!(!dynamic.contains("librtapi"), "the client needs librtapi beside libOpalOrchestra.so:\n{dynamic}");
    product
}

/// The reader built with pkg-config's flags for the installed rtapi reads from the host.
fn a_pkg_config_build_reads_from_the_host(dir: &Path, prefix: &Path, pc_path: &Path, reader: &Path, ns: &str) {
    let mut pc = Command::new("pkg-config");
    pc.args(["--cflags", "--libs", "rtapi"]).env("PKG_CONFIG_PATH", pc_path);
    let flags = run(pc, "pkg-config --cflags --libs rtapi");
    let exe = dir.join("reader-pkgconfig");
    let mut gcc = Command::new("gcc");
    gcc.args(["-std=c99", "-Wall", "-Wextra", "-Werror"])
        .arg(reader)
        .args(flags.split_whitespace())
        .arg(format!("-Wl,-rpath,{}", prefix.join("lib").display()))
        .arg("-o")
        .arg(&exe);
    run(gcc, "gcc with pkg-config's flags");
    reads_from_the_host(&exe, ns, "the pkg-config build");
}

/// CMake: the reader built with find_package(tutti), and the product's way (RTAPI.h + a
/// library OpalOrchestra), reads from the host.
fn cmake_builds_read_from_the_host(dir: &Path, prefix: &Path, reader: &Path, ns: &str) {
    for (name, body) in [
        ("find-package", "find_package(tutti 0.1 REQUIRED)\nadd_executable(reader ${READER})\ntarget_link_libraries(reader tutti::rtapi)\n"),
        (
            "product-style",
            "find_path(OPAL_ORCHESTRA_INCLUDE_DIR NAMES RTAPI.h REQUIRED)\nfind_library(OPAL_ORCHESTRA_LIBRARY NAMES OpalOrchestra REQUIRED)\nadd_executable(reader ${READER})\ntarget_include_directories(reader PRIVATE ${OPAL_ORCHESTRA_INCLUDE_DIR})\ntarget_link_libraries(reader ${OPAL_ORCHESTRA_LIBRARY})\n",
        ),
    ] {
        let src = dir.join(format!("cmake-{name}"));
        std::fs::create_dir_all(&src).unwrap();
        let text = format!("cmake_minimum_required(VERSION 3.18)\nproject(reader_{} C)\n{body}", name.replace('-', "_"));
        std::fs::write(src.join("CMakeLists.txt"), text).unwrap();
        let build = src.join("build");
        let mut configure = Command::new("cmake");
        configure
            .arg("-S")
            .arg(&src)
            .arg("-B")
            .arg(&build)
            .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix.display()))
            .arg(format!("-DREADER={}", reader.display()));
        run(configure, &format!("cmake configure ({name})"));
        let mut make = Command::new("cmake");
        make.arg("--build").arg(&build);
        run(make, &format!("cmake build ({name})"));
        reads_from_the_host(&build.join("reader"), ns, &format!("the CMake build ({name})"));
    }
}

/// pip install of the Python module into a fresh venv (from a copy: a build writes beside
/// its sources), run outside the checkout: it finds the library through pkg-config. Offline:
/// its build backend (setuptools) comes from the wheels launch-scripts/test.sh downloads.
fn a_pip_installed_module_reads_from_the_host(dir: &Path, prefix: &Path, pc_path: &Path, ns: &str) {
    let Some(_) = common::require_tool("python3", "python3-venv") else { return };
    let wheels = common::repo_root().join("target/wheels");
    let has_setuptools = std::fs::read_dir(&wheels)
        .map_err(|e| e.to_string())
        .map(|d| d.flatten().any(|e| e.file_name().to_string_lossy().starts_with("setuptools-")))
        .and_then(|found| if found { Ok(()) } else { Err("no setuptools wheel".into()) });
    let what = format!("the setuptools wheel in {}", wheels.display());
    let Some(()) = common::require(&what, has_setuptools) else { return };
    let pysrc = dir.join("python-src");
    std::fs::create_dir_all(&pysrc).unwrap();
    for f in ["pyproject.toml", "README.md", "tutti_rtapi.py"] {
        std::fs::copy(common::repo_root().join("python").join(f), pysrc.join(f)).unwrap();
    }
    let venv = dir.join("venv");
    let mut mk = Command::new("python3");
    mk.arg("-m").arg("venv").arg(&venv);
    run(mk, "python3 -m venv");
    let mut pip = Command::new(venv.join("bin/pip"));
    pip.args(["install", "-q", "--disable-pip-version-check", "--no-index", "--find-links"])
        .arg(&wheels)
        .arg(&pysrc)
        .current_dir(dir);
    run(pip, "pip install ./python");
    let mut py = python_component(&venv, dir, ns);
    py.env("PKG_CONFIG_PATH", pc_path);
    let out = run(py, "the pip-installed Python component");
    assert!(out.contains("z 1.5"), "{out}");
    assert!(out.contains(&prefix.join("lib/librtapi.so.0").display().to_string()), "the installed library: {out}");
}

/// A Python component of `venv` (run in `dir`, outside the checkout, with no
/// `TUTTI_RTAPI_LIB` or `PYTHONPATH`) that reads multiuav_uav2/Z for 5 steps from the host of
/// namespace `ns` and prints `z VALUE LIBRARY`: what it read and the library it loaded.
pub(crate) fn python_component(venv: &Path, dir: &Path, ns: &str) -> Command {
    let script = "import tutti_rtapi as rt\nwith rt.connect('multiuav_uav2', timeout=30) as c:\n    for _ in range(5):\n        with c.reading():\n            z = c.subscribe('Z')\n        with c.writing():\n            c.publish('Elevation', 2 * z)\nprint('z', z, rt._find_library())\n";
    let mut py = Command::new(venv.join("bin/python"));
    py.args(["-c", script])
        .current_dir(dir)
        .env("TUTTI_NAMESPACE", ns)
        .env_remove("TUTTI_RTAPI_LIB")
        .env_remove("PYTHONPATH");
    py
}
