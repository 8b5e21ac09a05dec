"""GentleBench: the method on dm_control contact tasks, the force read in the tolerance rule's unit."""
