// The one source of each precompiled-header target (fogmap_add_pch in cmake/fogmap_helpers.cmake).
int fogmap_pch_anchor = 0;
