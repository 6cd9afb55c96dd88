"""A diffuse render under an address-space limit (``ulimit -v``, RLIMIT_AS) is refused
before it starts, in one line naming the limit and its value, when the image and the
address space Mitsuba reserves do not fit together (past the limit Dr.Jit and Embree fail
inside the render); a cap below the image alone names the limit as the budget's cause."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

#: the child measures what it holds with the libraries loaded, caps its own address space
#: at ``used + image * share + Mitsuba's reservation + extra`` and runs the CLI's render
_CHILD = textwrap.dedent('''
    import json, resource, sys
    from render_inspect.cli import main
    from render_inspect.core.limits import address_space_used, mitsuba_address_space
    from render_inspect.pipeline import check_render_limits
    from render_inspect.scene import load_scene

    share, extra_mib, out = float(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
    sets = ["simulation.region=[-0.1,-0.1,0.1,0.1]", "render.diffuse.resolution=1024",
            "render.diffuse.spp=4"]
    need = max(check_render_limits(load_scene("sts_sinusoidal_grid", sets), kind="diffuse").values())
    limit = int(address_space_used() + share * need + mitsuba_address_space()
                + extra_mib * 2 ** 20)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    args = ["render", "sts_sinusoidal_grid", "--kind", "diffuse", "--surface", "design",
            "--out", out, "-q"]
    for s in sets:
        args += ["--set", s]
    rc = main(args)
    print(json.dumps({"rc": rc, "limit": limit, "need": need}))
''')


def _run(tmp_path, share, extra_mib):
    out = tmp_path / f"o{share}"
    p = subprocess.run([sys.executable, "-c", _CHILD, str(share), str(extra_mib), str(out)],
                       capture_output=True, text=True, timeout=600)
    return p, out


@pytest.mark.slow
@pytest.mark.parametrize("share, extra_mib, cause", [
    # the image fits the budget (80 % of the room), not beside Mitsuba's reservation
    (1.0, -100, "Mitsuba's own"),
    # the image alone is over the budget the limit leaves
    (0.5, 0, "memory budget"),
])
def test_a_diffuse_render_that_does_not_fit_the_limit_is_refused_first(tmp_path, share,
                                                                       extra_mib, cause):
    p, out = _run(tmp_path, share, extra_mib)
    assert "Traceback" not in p.stderr, p.stderr[-1500:]
    r = json.loads(p.stdout.strip().splitlines()[-1])
    assert r["rc"] == 1, (r, p.stderr[-800:])
    err = [ln for ln in p.stderr.strip().splitlines() if ln.strip()]
    assert len(err) == 1, err
    msg = err[0]
    assert "ulimit -v" in msg and cause in msg, msg
    # the limit's value, in the units the message writes it
    from render_inspect.core.limits import format_bytes
    assert format_bytes(r["limit"]) in msg, (msg, r)
    assert "None" not in msg and "^2" not in msg
    assert not out.exists()
