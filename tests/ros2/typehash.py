"""ROS 2's own type hashes of the interface package `tutti idl` wrote.

Usage: typehash.py OUT PKG

OUT is the directory `tutti idl` wrote into, PKG the package in it. Every `PKG/msg/*.idl` is
hashed by rosidl's generator (`rosidl_generator_type_description.generate_type_hash`, over
`rosidl_parser`), as `colcon build` of the package does; each `.msg` is read by rosidl's
`.msg` parser (`rosidl_adapter.parser`) and must declare the same fields, with the same types,
as its `.idl` (the generator hashes the `.idl` that rosidl_adapter makes of the `.msg`).
Prints one line per type, `PKG/msg/TYPE RIHS01_…`; exits 1 on a difference.

The rosidl modules are those of tests/ros2/rosidl/ (see its README.md); they need `lark`.
"""

import json
import pathlib
import sys
import tempfile

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent / 'rosidl'))

from rosidl_adapter.parser import parse_message_file  # noqa: E402
from rosidl_generator_type_description import generate_type_hash  # noqa: E402
from rosidl_parser import definition  # noqa: E402
from rosidl_parser.parser import parse_idl_file  # noqa: E402

# `.msg` primitive -> the IDL type rosidl_adapter writes for it.
MSG_TO_IDL = {
    'bool': 'boolean', 'byte': 'octet', 'char': 'uint8', 'float32': 'float', 'float64': 'double',
    'int8': 'int8', 'uint8': 'uint8', 'int16': 'int16', 'uint16': 'uint16',
    'int32': 'int32', 'uint32': 'uint32', 'int64': 'int64', 'uint64': 'uint64',
}


def idl_fields(locator):
    """(name, type, array length or None) of every member of the .idl's one message."""
    content = parse_idl_file(locator).content
    [message] = content.get_elements_of_type(definition.Message)
    out = []
    for m in message.structure.members:
        ty, size = m.type, None
        if isinstance(ty, definition.Array):
            ty, size = ty.value_type, ty.size
        elif isinstance(ty, definition.AbstractNestedType):
            raise ValueError(f'{locator.relative_path}: {m.name} is a sequence')
        name = '/'.join(ty.namespaced_name()) if isinstance(ty, definition.NamespacedType) else ty.typename
        out.append((m.name, name, size))
    return out


def msg_fields(pkg, path):
    """(name, type, array length or None) of every field of the .msg, in IDL terms."""
    spec = parse_message_file(pkg, str(path))
    out = []
    for f in spec.fields:
        t = f.type
        if t.is_array and (t.array_size is None or t.is_upper_bound):
            raise ValueError(f'{path}: {f.name} is a sequence')
        name = MSG_TO_IDL[t.type] if t.is_primitive_type() else f'{t.pkg_name}/msg/{t.type}'
        out.append((f.name, name, t.array_size if t.is_array else None))
    return out


def main():
    out, pkg = pathlib.Path(sys.argv[1]).resolve(), sys.argv[2]
    pkg_dir = out / pkg
    idls = sorted(p.relative_to(pkg_dir) for p in (pkg_dir / 'msg').glob('*.idl'))
    if not idls:
        sys.exit(f'no {pkg}/msg/*.idl under {out}')
    ok = True
    for rel in idls:
        from_idl = idl_fields(definition.IdlLocator(pkg_dir, rel))
        from_msg = msg_fields(pkg, pkg_dir / rel.with_suffix('.msg'))
        if from_idl != from_msg:
            print(f'{rel}: the .idl declares {from_idl}, the .msg {from_msg}', file=sys.stderr)
            ok = False
    with tempfile.TemporaryDirectory() as tmp:
        args = pathlib.Path(tmp) / 'args.json'
        args.write_text(json.dumps({
            'package_name': pkg,
            'output_dir': str(pathlib.Path(tmp) / 'out'),
            'idl_tuples': [f'{pkg_dir}:{rel}' for rel in idls],
            'include_paths': [],
        }))
        for written in generate_type_hash(str(args)):
            top = json.loads(pathlib.Path(written).read_text())['type_hashes'][0]
            print(top['type_name'], top['hash_string'])
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
