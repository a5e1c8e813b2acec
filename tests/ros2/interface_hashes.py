"""ROS 2's own type hashes of ROS 2 interface packages, computed from their sources.

Usage: interface_hashes.py TARBALL[,TARBALL...] DIR...

TARBALL is tests/ros2/jazzy/jazzy-src.tar.xz (and geometry2-jazzy-src.tar.xz beside it: several,
comma-separated, are read as one tree); each DIR is the folder of one interface package in
it (`ros2/rcl_interfaces/action_msgs`), the packages it depends on before it. Every `msg/*.msg`,
`srv/*.srv` and `action/*.action` of each is read by rosidl's own parser
(`rosidl_adapter.parser`) and written as the `.idl` that rosidl_adapter's templates make of it;
rosidl's type-description generator (`rosidl_generator_type_description.generate_type_hash`,
over `rosidl_parser`) then hashes each package as `colcon build` does, with the descriptions of
the packages before it. For a service and an action it derives and hashes, as in a build, the
implicit types: a service's `_Request`, `_Response` and `_Event`; an action's `_Goal`,
`_Result`, `_Feedback`, `_SendGoal` and `_GetResult` (services, each with their own implicit
types) and `_FeedbackMessage`.

Prints one line per type, `PKG/KIND/TYPE RIHS01_...`.

The `.idl` is written here, not by rosidl_adapter's templates (they need empy): each message is
one struct, its fields in order with the IDL type rosidl_adapter gives them (`get_idl_type`
below) and a fixed-size array through a typedef, as `struct.idl.em` writes them, and an empty
message has the one member `uint8 structure_needs_at_least_one_member`, as the template gives
it. Constants, default values and comments are left out: none of them enters a type hash
(constants are not members; `calculate_type_hash` drops default values).

The rosidl modules are those of tests/ros2/rosidl/ (see its README.md); they need `lark`.
"""

import json
import pathlib
import sys
import tarfile
import tempfile
import xml.etree.ElementTree as ET

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent / 'rosidl'))

from rosidl_adapter.parser import parse_action_string  # noqa: E402
from rosidl_adapter.parser import parse_message_string  # noqa: E402
from rosidl_adapter.parser import parse_service_string  # noqa: E402
from rosidl_generator_type_description import generate_type_hash  # noqa: E402

# rosidl_adapter/msg/__init__.py's MSG_TYPE_TO_IDL.
MSG_TYPE_TO_IDL = {
    'bool': 'boolean', 'byte': 'octet', 'char': 'uint8', 'int8': 'int8', 'uint8': 'uint8',
    'int16': 'int16', 'uint16': 'uint16', 'int32': 'int32', 'uint32': 'uint32',
    'int64': 'int64', 'uint64': 'uint64', 'float32': 'float', 'float64': 'double',
    'string': 'string', 'wstring': 'wstring',
}


def get_idl_type(type_):
    """rosidl_adapter/msg/__init__.py's get_idl_type."""
    if type_.is_primitive_type():
        identifier = MSG_TYPE_TO_IDL[type_.type]
        if identifier in ('string', 'wstring') and type_.string_upper_bound is not None:
            identifier += f'<{type_.string_upper_bound}>'
    else:
        identifier = f'{type_.pkg_name}::msg::{type_.type}'
    if not type_.is_array:
        return identifier
    if type_.is_fixed_size_array():
        return f'{identifier}[{type_.array_size}]'
    if not type_.is_upper_bound:
        return f'sequence<{identifier}>'
    return f'sequence<{identifier}, {type_.array_size}>'


def identifier_of(idl_type):
    """struct.idl.em's get_idl_type_identifier."""
    return idl_type.replace('::', '__').replace('<', '__').replace('>', '').replace('[', '__').replace(']', '')


def struct(msg):
    """The typedefs and the struct struct.idl.em writes for a message (no constants)."""
    typedefs, members = {}, []
    for field in msg.fields:
        idl_type = get_idl_type(field.type)
        if field.type.is_fixed_size_array():
            base = idl_type.split('[', 1)[0]
            base_id = base.replace('::', '__')
            if base_id != base:
                typedefs[base_id] = base
            typedefs[identifier_of(idl_type) + f'[{field.type.array_size}]'] = base_id
            idl_type = identifier_of(idl_type)
        members.append(f'      {idl_type} {field.name};')
    if not members:
        members.append('      uint8 structure_needs_at_least_one_member;')
    lines = [f'    typedef {v} {k};' for k, v in typedefs.items()]
    lines += [f'    struct {msg.msg_name} {{', *members, '    };']
    return lines


def to_idl(pkg, kind, path):
    """The .idl text of one .msg, .srv or .action file."""
    text, stem = path.read_text(encoding='utf-8'), path.stem
    if kind == 'msg':
        msgs = [parse_message_string(pkg, stem, text)]
    elif kind == 'srv':
        srv = parse_service_string(pkg, stem, text)
        msgs = [srv.request, srv.response]
    else:
        action = parse_action_string(pkg, stem, text)
        msgs = [action.goal, action.result, action.feedback]
    lines = [f'module {pkg} {{', f'  module {kind} {{']
    for msg in msgs:
        lines += struct(msg)
    lines += ['  };', '};', '']
    return '\n'.join(lines)


def extract(tarballs, dirs, into):
    prefixes = tuple(d.rstrip('/') + '/' for d in dirs)
    for tarball in tarballs:
        with tarfile.open(tarball, 'r:xz') as tar:
            members = [m for m in tar.getmembers() if m.name.startswith(prefixes) and (m.isfile() or m.isdir())]
            if any(m.name.startswith('/') or '..' in pathlib.PurePosixPath(m.name).parts for m in members):
                sys.exit(f'{tarball}: a path outside the archive')
            tar.extractall(into, members=members)
    tarball = ', '.join(str(t) for t in tarballs)
    for d in dirs:
        if not (into / d / 'package.xml').is_file():
            sys.exit(f'{tarball}: no package in {d}')


def main():
    tarballs, dirs = [pathlib.Path(t) for t in sys.argv[1].split(',')], sys.argv[2:]
    if not dirs:
        sys.exit(__doc__)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        extract(tarballs, dirs, tmp / 'src')
        include_paths = []
        for d in dirs:
            pkg_src = tmp / 'src' / d
            pkg = ET.parse(pkg_src / 'package.xml').getroot().findtext('name').strip()
            idl_dir, out_dir = tmp / 'idl' / pkg, tmp / 'out' / pkg
            rels = []
            for kind, suffix in (('msg', '.msg'), ('srv', '.srv'), ('action', '.action')):
                for path in sorted((pkg_src / kind).glob(f'*{suffix}')):
                    rel = pathlib.Path(kind) / (path.stem + '.idl')
                    (idl_dir / kind).mkdir(parents=True, exist_ok=True)
                    (idl_dir / rel).write_text(to_idl(pkg, kind, path), encoding='utf-8')
                    rels.append(rel)
            if not rels:
                sys.exit(f'{d}: no interfaces')
            args = tmp / f'{pkg}-args.json'
            args.write_text(json.dumps({
                'package_name': pkg,
                'output_dir': str(out_dir),
                'idl_tuples': [f'{idl_dir}:{rel}' for rel in rels],
                'include_paths': include_paths,
            }))
            for written in generate_type_hash(str(args)):
                top = json.loads(pathlib.Path(written).read_text())['type_hashes'][0]
                print(top['type_name'], top['hash_string'])
            include_paths.append(f'{pkg}:{out_dir}')


if __name__ == '__main__':
    main()
