int fogmap_core_pch_anchor = 0;
