"""The tactics layer (thesis sec. 4.6): one tactic per module, a common contract (:mod:`.base`) and the
state machine that chooses among them (:mod:`.selector`)."""
