//! `tutti idl DDF --out DIR`: writes the typed DDS / ROS 2 interface of a DDF
//! (`docs/gateway.md`): OMG IDL 4 for every set, and a ROS 2 interface package. The files themselves come from
//! `tutti_ros2::idl`; this module only writes them.

use std::path::PathBuf;

use anyhow::Context as _;
use tutti_core::mapping;
use tutti_ros2::idl;

use super::{load_ddf, CliResult, Failure};

/// Write the typed interface of a DDF: OMG IDL 4 for every set (as ROS 2's rosidl writes it,
/// and under the mangled name the gateway uses on the wire), and a ROS 2 interface package
/// (package.xml, CMakeLists.txt, msg/) that `colcon build` builds.
#[derive(Debug, clap::Args)]
#[command(after_help = "Writes DIR/PKG/ where PKG is the DDF's file stem + _msgs:\n  \
    PKG/msg/TYPE.idl           IDL of PKG::msg::TYPE, as rosidl writes it\n  \
    PKG/msg/dds_/TYPE_.idl     IDL of PKG::msg::dds_::TYPE_, the type name on the wire\n  \
    PKG/msg/TYPE.msg           ROS 2 message\n  \
    PKG/package.xml, PKG/CMakeLists.txt\n\
    TYPE is CamelCase(domain) + Publish/Subscribe; each bus is a type of its own.\n\
    Each file names its type's ROS 2 type hash (RIHS01_…) in a comment: what the gateway announces.\n\n\
    Examples:\n  \
    tutti idl ddf/multiuav.ddf --out idl\n  \
    idlc -I idl idl/multiuav_msgs/msg/dds_/MultiuavUav1Publish_.idl\n  \
    cp -r idl/multiuav_msgs ~/ros2_ws/src/ && cd ~/ros2_ws && colcon build --packages-select multiuav_msgs")]
pub struct Args {
    /// The DDF to generate the interface of.
    #[arg(value_name = "DDF")]
    file: PathBuf,
    /// Directory to write the package directory into (created if missing; existing files
    /// of the same name are replaced).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

pub fn run(args: Args) -> CliResult {
    let model = load_ddf(&args.file)?;
    let package = mapping::package_name(&args.file);
    let files = idl::generate(&model, &package).map_err(Failure::invalid)?;
    for file in &files {
        let path = args.out.join(&file.path);
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create directory {}", dir.display()))?;
        }
        std::fs::write(&path, &file.contents).with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    println!("{}: {} file(s) of ROS 2 package {package} in {}", args.file.display(), files.len(), args.out.display());
    Ok(())
}
