"""The one error family of smibjax: every refusal of user input is a `ParameterError`.

A value outside its meaning, a file that cannot be read, a case that cannot be built,
a parameter name a case lacks, a power flow with no solution: each raises a subclass of
`ParameterError` (itself a `ValueError`) whose message is one line naming the value and
what is allowed. Callers that only want to know "was the input refused?" catch
`ParameterError`; the subclasses say where the refusal came from:

- `smibjax.grid.PsseError`: a PSS/E raw or dyr file (`file:line: MODEL field NAME: ...`);
- `smibjax.grid.CaseError`: a case that cannot be built from its files;
- `smibjax.grid.ParamError`: a parameter name (`MODEL[GEN].NAME`) the case lacks;
- `smibjax.grid.PowerFlowError`: a power flow that does not converge.

This module imports nothing but the standard library, so that readers of files (and
the command line's early checks) can raise these errors before JAX is loaded.
"""

from __future__ import annotations

__all__ = ["ParameterError"]


class ParameterError(ValueError):
    """A parameter value outside its allowed range. The message is one line that names
    the value and what is allowed."""
