"""The run stage: the 240 Hz loop of decisions and paths (brain -> Intent -> agent -> head,
and the prey), for one creature (loop.run) or a crowd in lockstep (crowd.run_crowd). Its
output is a small RunRecord per creature (record.py): the head path per step, the per-frame
drives and prey states, the timeline. The solve stage (baker/solve) turns it into frames."""
