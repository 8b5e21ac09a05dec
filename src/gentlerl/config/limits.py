"""Upper bounds of the sizes a config may ask for (each group's ``bounds`` read them)."""

# Upper bounds of the sizes: far above what any scale uses (the paper's: 1M transitions, 500k
# frames, 400-unit layers, 5 members), low enough that no single value exhausts a 24 GB machine
# before it starts (what a value past them would do: allocate until the memory runs out).
#: env frames of a run (~100 days at 1,000 frames/s).
MAX_FRAMES = 10**10
#: transitions a replay buffer keeps (10x the paper's).
MAX_TRANSITIONS = 10**7
#: transitions per (model) update.
MAX_BATCH = 65536
#: units of a hidden layer (a 4096 x 4096 layer: 64 MiB of float32).
MAX_WIDTH = 4096
#: hands stepped together (a batched collector env, one evaluation's episodes).
MAX_HANDS = 256
#: torch / physics threads of one process.
MAX_THREADS = 256
#: seeds of one seed group (``gentlerl seeds``): each holds its own replay, reward models,
#: learner and collector in the one process (10,000 at CPU scale: 7.3 GB before the first
#: update), and the group's point, one batched update on a GPU, is reached at a handful.
MAX_SEEDS = 64
#: a run's seed. numpy's RandomState takes seeds below 2**32 (torch's up to 2**64 - 1), and a run
#: seeds more than its seed: its evaluation hands with seed + 10,000, collector worker i with
#: seed + i and a resumed collector with seed + the frames so far (``training.builders``). The
#: lower half of numpy's range leaves the upper half to those offsets (a run's seed + its
#: ``collector.total_frames`` is checked too: the frames alone may pass 2**31).
MAX_SEED = 2**31 - 1
#: a force or impact a setting may state (N; ``gentleness.tolerance``). The penalty reads
#: impacts in units of tolerance / lambda_2 in float32: at 1e6 N a 1 mN impact still costs a
#: normal float32 penalty (-4e-11), where 1e300 N makes the unit inf and every impact cost 0.
#: A megannewton is far above any hand's or robot's forces (the hand's tolerance: 2 N).
MAX_FORCE = 1e6
#: the smallest such force: a micronewton, far below any hand's sensing, and far above where the
#: unit tolerance / lambda_2 underflows float32 (1e-300 made it 0, every impact an infinite
#: number of units, refused as a force-unit fault instead of as the setting it is).
MIN_FORCE = 1e-6
#: a weight or scale on a reward or a penalty (``gentleness.multiplier_base``, the multiplier's
#: integral cap, the surprise scales): it multiplies float32 rewards and critic values, and
#: 1e6 times a value of the critics' support (|v| <= 1e3) stays far inside float32.
MAX_WEIGHT = 1e6
#: a PID gain of the multiplier: its error is in doublings (at most ~300 for float32 impacts),
#: so 1e3 moves the weight by at most ~3e5 a step, inside :data:`MAX_WEIGHT`'s range.
MAX_GAIN = 1e3
