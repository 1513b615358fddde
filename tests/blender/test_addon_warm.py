"""The add-on's warm-up of the core (issue #35): off in background mode; started, it loads the chain's libraries
and the head prior on a thread of its own, and operators wait for it."""
import sys

MODULE = "bl_ext.pdeface_test.pdeface"


def test_warm_up_is_off_in_background_and_loads_the_core_on_its_thread_when_started(bpy):
    from pdeface.head.prior import load_head_prior
    from pdeface.rig import CHAIN_MODULES

    warm = __import__(MODULE, fromlist=["warm"]).warm
    assert bpy.app.background and not bpy.app.timers.is_registered(warm.start)  # no thread beside a script
    warm.start()
    warm.start()  # once a session
    assert len(warm._started) == 1 and warm._started[0].name == "pdeface warm-up"
    assert bpy.ops.pdeface.add_default_face() == {"FINISHED"}  # an operator waits for it first
    assert not warm._started[0].is_alive()
    assert all(m in sys.modules for m in CHAIN_MODULES)
    assert load_head_prior.cache_info().currsize == 1
