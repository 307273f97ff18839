import itertools
from pathlib import Path

import pytest

from tasks.clips.snippets import SnippetId, format_snippet_id, parse_snippet_id, snippets_of_clip, split_snippets
from tasks.clips.sources import ClipSourceError, find_cmu_file, resolve_clip_file


def test_split_matches_seed_example():
    assert split_snippets(529) == [(0, 198), (165, 363), (330, 529)]


def test_split_puts_the_whole_remainder_on_the_last_snippet():
    # MoCapAct's rule: equal lengths, remainder last (spreading it would give 0-182, 149-332, 299-482).
    assert split_snippets(482) == [(0, 182), (149, 331), (298, 482)]
    assert split_snippets(760) == [(0, 178), (145, 323), (290, 468), (435, 613), (580, 760)]


@pytest.mark.parametrize("length", [1, 16, 210])
def test_short_clips_stay_whole(length):
    assert split_snippets(length) == [(0, length)]


@pytest.mark.parametrize("length", [*range(211, 3200, 7), 6371])
def test_split_properties(length):
    snippets = split_snippets(length)
    assert snippets[0][0] == 0 and snippets[-1][1] == length
    sizes = [end - start for start, end in snippets]
    assert len(set(sizes[:-1])) <= 1 and max(sizes[:-1], default=0) <= 210  # equal, at most max_len ...
    assert 0 <= sizes[-1] - sizes[0] < len(snippets)  # ... and the last one takes the remainder
    for (_, end), (next_start, _) in itertools.pairwise(snippets):
        assert end - next_start == 33
    # fewest snippets: one fewer could not respect the maximum length
    fewer = len(snippets) - 1
    if fewer >= 1:
        assert (length + (fewer - 1) * 33) / fewer > 210


def test_get_up_clips_are_never_cut(monkeypatch):
    from dm_control.locomotion.tasks.reference_pose import cmu_subsets

    import tasks.clips.snippets as module

    get_up = cmu_subsets.GET_UP.ids[0]
    listed = module.mocapact_snippets()
    assert all(len(listed[c]) == 1 for c in cmu_subsets.GET_UP.ids if c in listed)  # MoCapAct keeps them whole too
    monkeypatch.setattr(module, "mocapact_snippets", dict)  # the rule alone, as for clips MoCapAct does not list
    assert snippets_of_clip(get_up, 900) == [SnippetId(get_up, 0, 900)]
    assert len(snippets_of_clip("CMU_009_12", 529)) == 3


@pytest.mark.parametrize("text", ["CMU_006_12-151-336", "SYN_walk_slow-0-182", "SYN_stand"])
def test_snippet_id_round_trip(text):
    snippet = parse_snippet_id(text)
    assert str(snippet) == text
    assert parse_snippet_id(format_snippet_id(snippet.clip_id, snippet.start, snippet.end)) == snippet


@pytest.mark.parametrize("text", ["CMU-006-12-1-2", "CMU_006_12-336-151", "CMU_006_12-a-3", "", "bad id-1-2", "A-1"])
def test_bad_snippet_ids_are_refused(text):
    with pytest.raises(ValueError, match=r"snippet id|clip id"):
        parse_snippet_id(text)


def test_frame_range_follows_dm_control_slicing():
    # dm_control includes the end step when it lies inside the clip ...
    assert SnippetId("C", 0, 198).frame_range(529) == (0, 199)
    # ... and stops at the last frame when the end step is the clip length.
    assert SnippetId("C", 330, 529).frame_range(529) == (330, 529)
    assert SnippetId("C").frame_range(529) == (0, 529)
    with pytest.raises(ValueError, match="ends at step 600"):
        SnippetId("C", 0, 600).frame_range(529)
    with pytest.raises(ValueError, match="starts at frame 529"):
        SnippetId("C", 529, 600).frame_range(529)


def test_cmu_clip_without_file_says_where_to_put_it(monkeypatch, tmp_path):
    monkeypatch.setattr(Path, "home", lambda: tmp_path)
    with pytest.raises(ClipSourceError, match=r"\.dm_control.*MOCAP_HIERARCHY_CMU_FILE") as shipped:
        resolve_clip_file(None, ["CMU_016_22"])
    # a clip the shipped real library holds: the library is named first, as nothing needs downloading
    assert "They are in the shipped clip library cmu-locomotion-v1: pass --clips cmu-locomotion-v1" in str(
        shipped.value
    )
    with pytest.raises(ClipSourceError, match=r"\.dm_control") as elsewhere:
        resolve_clip_file(None, ["CMU_016_22", "CMU_140_01"])  # the second is in no shipped library
    assert "shipped clip library" not in str(elsewhere.value)


def test_cmu_file_from_environment(monkeypatch, tmp_path):
    fake = tmp_path / "cmu.h5"
    fake.write_bytes(b"x")
    monkeypatch.setenv("MOCAP_HIERARCHY_CMU_FILE", str(fake))
    assert find_cmu_file() == fake
    monkeypatch.setenv("MOCAP_HIERARCHY_CMU_FILE", str(tmp_path / "missing.h5"))
    with pytest.raises(ClipSourceError, match=r"missing\.h5"):
        find_cmu_file()


def test_explicit_clip_file_must_exist(tmp_path):
    with pytest.raises(ClipSourceError, match="does not exist"):
        resolve_clip_file(tmp_path / "nope.h5", ["SYN_stand"])


def test_cmu_file_found_in_dm_control_cache_only_at_its_exact_size(monkeypatch, tmp_path):
    from tasks.clips.sources import CMU_2020_BYTES, CMU_2020_FILENAME

    monkeypatch.setattr(Path, "home", lambda: tmp_path)
    cached = tmp_path / ".dm_control" / CMU_2020_FILENAME
    cached.parent.mkdir()
    with cached.open("wb") as f:  # sparse: no disk space used
        f.truncate(CMU_2020_BYTES - 1)
    assert find_cmu_file() is None  # a partial download is not used
    with cached.open("r+b") as f:
        f.truncate(CMU_2020_BYTES)
    assert find_cmu_file() == cached
    assert resolve_clip_file(None, ["CMU_016_22"]) == cached


def test_mocapact_snippet_list_is_shipped_whole():
    from tasks.clips.snippets import mocapact_snippets

    listed = mocapact_snippets()
    assert len(listed) == 836 and sum(len(s) for s in listed.values()) == 2589
    assert [str(s) for s in listed["CMU_091_02"]] == ["CMU_091_02-0-182", "CMU_091_02-149-331", "CMU_091_02-298-482"]
    # The rule reproduces 806 clips exactly; the other 30 are cut irregularly in MoCapAct's list.
    by_rule = sum(split_snippets(s[-1].end) == [(x.start, x.end) for x in s] for s in listed.values())
    assert by_rule == 806
    irregular = listed["CMU_015_03"]  # 3482 steps: the rule would start the second snippet at 164 too, but ...
    assert (irregular[-1].start, irregular[-1].end) == (3280, 3482)
    assert split_snippets(3482)[-1] != (3280, 3482)  # ... MoCapAct's last snippet is not the rule's


def test_cmu_clips_use_mocapact_ids_and_other_clips_the_rule():
    from tasks.clips.snippets import mocapact_snippets

    assert snippets_of_clip("CMU_015_03", 3482) == list(mocapact_snippets()["CMU_015_03"])
    assert [str(s) for s in snippets_of_clip("CMU_091_02", 482)][1] == "CMU_091_02-149-331"
    with pytest.raises(ValueError, match="not the CMU 2020 file"):
        snippets_of_clip("CMU_091_02", 500)
    assert snippets_of_clip("MY_clip_01", 482) == [SnippetId("MY_clip_01", s, e) for s, e in split_snippets(482)]
