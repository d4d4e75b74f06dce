"""YAML load and dump through libyaml when PyYAML has it (about 10x faster), else pure Python."""
import yaml

_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)

#: The error every loader raises on bad YAML.
YAMLError = yaml.YAMLError


def load(stream):
    """Parse one YAML document (str, bytes or file) with the safe loader."""
    return yaml.load(stream, Loader=_LOADER)


def dump(value):
    """Return ``value`` as block-style YAML, keys in insertion order, no trailing newline."""
    return yaml.dump(value, Dumper=_DUMPER, sort_keys=False,
                     default_flow_style=False).rstrip('\n')
