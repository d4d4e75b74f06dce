"""
The root of the package's errors: every error it raises for bad input or a failed run.

Each error class of the package derives from :class:`LeadscrewError` and from
the built-in exception it has always been (``ValueError`` for a bad value,
``OSError`` for a file, ...), so ``except leadscrew_sim.LeadscrewError``
catches all of them and older ``except ValueError`` code keeps working. Its
message is one line that names the parameter or field, the value and the
allowed range.

=====================  ==========================  =====================================
class                  also a                      raised for
=====================  ==========================  =====================================
ParameterError         ValueError                  a parameter outside its range
SimulationFault        FloatingPointError          a state that became non-finite
RecordingError         ValueError                  a recording that cannot be read
DecodeError            ValueError                  bytes that are not the CDR of a type
DescriptionError       RuntimeError                a URDF that cannot be rendered
RunFileError           OSError                     a run file that cannot be written
ServeError             OSError                     a Foxglove server that cannot start
DefinitionNotFound...  LookupError                 a message definition not found
RunError               Exception                   an offline run that cannot go on
MappingError           RunError                    a recording that does not map to an axis
ExciteError            RuntimeError                the exciter cannot reach the node
StartupError           Exception                   the node cannot start
=====================  ==========================  =====================================
"""

__all__ = ['LeadscrewError']


class LeadscrewError(Exception):
    """The base of every error leadscrew_sim raises (see the module's table)."""
