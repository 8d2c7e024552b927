"""Quality profiles: samples per pixel and sample groups."""


def test_every_sample_group_gets_at_least_two_samples_where_the_scene_has_them():
    from pbrbench.quality import get_quality

    d = get_quality("draft")
    assert d.groups == 4
    assert d.spp(64) == 8            # 64 / 16 = 4 would leave one sample per group
    assert d.spp(288) == 18          # scaled as before
    assert d.spp(6) == 6             # never more than the scene file asks
    assert get_quality("standard").spp(64) == 64
