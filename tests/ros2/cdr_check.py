"""tutti-ros2's CDR held against Cyclone DDS's Python binding.

Usage: cdr_check.py INTERFACES CASES

INTERFACES is crates/tutti-ros2/interfaces (PKG/msg/*.msg, PKG/srv/*.srv, PKG/action/*.action).
Every file is read by rosidl's own parser (`rosidl_adapter.parser`, tests/ros2/rosidl/), and the
messages rosidl makes of each service and action are derived here as rosidl_parser's
`definition.Service` and `definition.Action` derive them (a service's `_Request`, `_Response` and
`_Event`; an action's `_Goal`, `_Result`, `_Feedback`, `_SendGoal_…`, `_GetResult_…` and
`_FeedbackMessage`). Each message becomes an `IdlStruct` built at run time
(`cyclonedds.idl.make_idl_struct`) with the IDL types rosidl_adapter gives its fields (`char` is
`uint8`, `byte` is `octet`, `T[N]` an array, `T[<=N]` a bounded sequence, `string<=N` a bounded
string).

CASES is a JSON list of `{"type": "PKG/KIND/NAME", "value": {...}, "cdr": "HEX"}`: a value of every
field of the message and the plain CDR body tutti encodes for it. For each, Cyclone encodes the
value as XCDR1 (plain CDR, little-endian, as ROS 2 sends it) and its body (after the 4-byte
encapsulation header) must be the case's bytes; Cyclone decodes the case's bytes (behind a CDR_LE
header) and must find the value. Prints `checked N cases of M types`, or each difference and exits
with 1. `wstring` is refused: tutti's codec has none.

Needs `cyclonedds` (the version launch-scripts/test.sh installs).
"""

import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent / 'rosidl'))

from cyclonedds.idl import Endianness, make_idl_struct  # noqa: E402
from cyclonedds.idl import types  # noqa: E402
from rosidl_adapter.parser import parse_action_string  # noqa: E402
from rosidl_adapter.parser import parse_message_string  # noqa: E402
from rosidl_adapter.parser import parse_service_string  # noqa: E402

PRIMITIVES = {
    'bool': bool, 'byte': types.byte, 'char': types.uint8, 'int8': types.int8, 'uint8': types.uint8,
    'int16': types.int16, 'uint16': types.uint16, 'int32': types.int32, 'uint32': types.uint32,
    'int64': types.int64, 'uint64': types.uint64, 'float32': types.float32, 'float64': types.float64,
}

HEADER_LE = bytes([0, 1, 0, 0])


class Unsupported(Exception):
    pass


def field_of(t):
    """(base, shape, size) of a rosidl_adapter Type."""
    if t.is_primitive_type():
        base = (t.type, t.string_upper_bound) if t.type in ('string', 'wstring') else ('prim', t.type)
    else:
        base = ('nested', f'{t.pkg_name}/msg/{t.type}')
    if not t.is_array:
        return base, 'single', None
    if t.is_fixed_size_array():
        return base, 'array', t.array_size
    return base, ('bounded' if t.is_upper_bound else 'unbounded'), t.array_size


def nested(name, shape='single', size=None):
    return ('nested', name), shape, size


def fields_of(msg):
    fields = [(f.name, field_of(f.type)) for f in msg.fields]
    return fields or [('structure_needs_at_least_one_member', (('prim', 'uint8'), 'single', None))]


def add_service(table, pkg, kind, name, request, response):
    """A service's request, response and event (definition.Service)."""
    table[f'{pkg}/{kind}/{name}_Request'] = request
    table[f'{pkg}/{kind}/{name}_Response'] = response
    table[f'{pkg}/{kind}/{name}_Event'] = [
        ('info', nested('service_msgs/msg/ServiceEventInfo')),
        ('request', nested(f'{pkg}/{kind}/{name}_Request', 'bounded', 1)),
        ('response', nested(f'{pkg}/{kind}/{name}_Response', 'bounded', 1)),
    ]


def add_action(table, pkg, name, action):
    """An action's messages and services (definition.Action)."""
    prefix = f'{pkg}/action/{name}'
    table[f'{prefix}_Goal'] = fields_of(action.goal)
    table[f'{prefix}_Result'] = fields_of(action.result)
    table[f'{prefix}_Feedback'] = fields_of(action.feedback)
    goal_id = ('goal_id', nested('unique_identifier_msgs/msg/UUID'))
    add_service(table, pkg, 'action', f'{name}_SendGoal',
                [goal_id, ('goal', nested(f'{prefix}_Goal'))],
                [('accepted', (('prim', 'bool'), 'single', None)),
                 ('stamp', nested('builtin_interfaces/msg/Time'))])
    add_service(table, pkg, 'action', f'{name}_GetResult',
                [goal_id],
                [('status', (('prim', 'int8'), 'single', None)), ('result', nested(f'{prefix}_Result'))])
    table[f'{prefix}_FeedbackMessage'] = [goal_id, ('feedback', nested(f'{prefix}_Feedback'))]


def read_interfaces(root):
    """Every message's fields, by name."""
    table = {}
    for pkg_dir in sorted(p for p in root.iterdir() if p.is_dir()):
        pkg = pkg_dir.name
        for path in sorted((pkg_dir / 'msg').glob('*.msg')):
            msg = parse_message_string(pkg, path.stem, path.read_text(encoding='utf-8'))
            table[f'{pkg}/msg/{path.stem}'] = fields_of(msg)
        for path in sorted((pkg_dir / 'srv').glob('*.srv')):
            srv = parse_service_string(pkg, path.stem, path.read_text(encoding='utf-8'))
            add_service(table, pkg, 'srv', path.stem, fields_of(srv.request), fields_of(srv.response))
        for path in sorted((pkg_dir / 'action').glob('*.action')):
            add_action(table, pkg, path.stem, parse_action_string(pkg, path.stem, path.read_text(encoding='utf-8')))
    return table


class Types:
    """The IdlStruct of each message, made when first needed."""

    def __init__(self, table):
        self.table, self.classes = table, {}

    def base(self, base):
        kind, arg = base
        if kind == 'prim':
            return PRIMITIVES[arg]
        if kind == 'string':
            return types.bounded_str[arg] if arg else str
        if kind == 'wstring':
            raise Unsupported('wstring')
        return self.struct(arg)

    def field(self, field):
        base, shape, size = field
        t = self.base(base)
        if shape == 'single':
            return t
        if shape == 'array':
            return types.array[t, size]
        if shape == 'bounded':
            return types.sequence[t, size]
        return types.sequence[t]

    def struct(self, name):
        if name not in self.classes:
            pkg, kind, short = name.split('/')
            fields = {f: self.field(ft) for f, ft in self.table[name]}
            self.classes[name] = make_idl_struct(f'{pkg}_{kind}_{short}', f'{pkg}::{kind}::dds_::{short}_', fields)
        return self.classes[name]

    def to_py(self, field, value):
        base, shape, _ = field
        if shape == 'single':
            return self.one_to_py(base, value)
        return [self.one_to_py(base, v) for v in value]

    def one_to_py(self, base, value):
        if base[0] == 'nested':
            return self.struct(base[1])(**{f: self.to_py(ft, value[f]) for f, ft in self.table[base[1]]})
        if base == ('prim', 'float32') or base == ('prim', 'float64'):
            return float(value)
        return value

    def from_py(self, field, value):
        base, shape, _ = field
        if shape == 'single':
            return self.one_from_py(base, value)
        return [self.one_from_py(base, v) for v in value]

    def one_from_py(self, base, value):
        if base[0] == 'nested':
            return {f: self.from_py(ft, getattr(value, f)) for f, ft in self.table[base[1]]}
        return value


def check(types_, case):
    """The differences for one case, as text."""
    name, value, ours = case['type'], case['value'], bytes.fromhex(case['cdr'])
    cls = types_.struct(name)
    sample = types_.one_to_py(('nested', name), value)
    encoded = sample.serialize(endianness=Endianness.Little, use_version_2=False)
    problems = []
    if encoded[:4] != HEADER_LE:
        problems.append(f'{name}: Cyclone wrote the header {encoded[:4].hex()}, not CDR_LE')
    if encoded[4:] != ours:
        problems.append(f'{name}: Cyclone encodes\n  {encoded[4:].hex()}\ntutti encodes\n  {ours.hex()}')
    try:
        decoded = types_.one_from_py(('nested', name), cls.deserialize(HEADER_LE + ours, has_header=True))
    except Exception as e:  # noqa: BLE001 (any failure of Cyclone's decoder is a difference)
        return problems + [f'{name}: Cyclone cannot decode tutti\'s bytes: {e!r}']
    if decoded != value:
        problems.append(f'{name}: Cyclone decodes tutti\'s bytes as\n  {decoded}\nnot\n  {value}')
    return problems


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    table = read_interfaces(pathlib.Path(sys.argv[1]))
    cases = json.loads(pathlib.Path(sys.argv[2]).read_text(encoding='utf-8'))
    types_ = Types(table)
    problems = []
    for case in cases:
        try:
            problems += check(types_, case)
        except Unsupported as e:
            problems.append(f'{case["type"]}: {e} has no codec in tutti')
    for p in problems:
        print(p)
    if problems:
        sys.exit(1)
    print(f'checked {len(cases)} cases of {len({c["type"] for c in cases})} types ({len(table)} known)')


if __name__ == '__main__':
    main()
