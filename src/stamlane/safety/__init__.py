"""The safety floor: what stamlane promises about untrusted input, sizes and outputs (docs/safety.md).

Each check lives in one module, and every other floor may use them; they import nothing of stamlane's but
`stamlane.types` and ``stamlane_eval``:

- `stamlane.safety.boundary`: a command's expected failure is one line on stderr and exit status 2;
- `stamlane.safety.budget`: every size a config, a flag or a checkpoint sets is checked before it is allocated;
- `stamlane.safety.paths`: the path gate: what a path a command receives is (kind, size, root, a name that cannot
  be used), answered without raising; one line for what a reader cannot take;
- `stamlane.safety.guard`: what a command writes (atomically) never replaces or lands among what it reads;
- `stamlane.safety.checkpoints`: a checkpoint read with weights only, a one-line error for a bad file (a leaf);
- `stamlane.safety.images`: frames and videos read within limits (a truncated file is unreadable, a bomb refused).

What a stored run may name (the closed registry) is the training shell's: `stamlane.training.registry`.
"""
