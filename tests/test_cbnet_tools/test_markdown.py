import pytest

from cbnet_tools.markdown import markdown_table


def test_markdown_table_lines_and_alignment():
    assert markdown_table(['a', 'b', 'c'], [[1, 2.5, 'x']], align='lr') == [
        '| a | b | c |', '|---|---:|---|', '| 1 | 2.5 | x |']
    assert markdown_table(['a'], []) == ['| a |', '|---|']


def test_markdown_table_refuses_a_ragged_row():
    with pytest.raises(ValueError, match='2 cells under 3 columns'):
        markdown_table(['a', 'b', 'c'], [[1, 2]])
